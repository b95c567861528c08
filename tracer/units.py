"""Units of the light-transport part of `tracer`, stated once.

Every length is in metres (m), every luminous flux in lumens (lm), luminous intensity in candelas
(cd = lm/sr), illuminance and luminous exitance in lux (lx = lm/m²), radiant power in watts (W) and
wavelengths in nanometres (nm). Angles in the public bodies (docs/DESIGN.md JSON) are in degrees; inside
the kernels they are radians. Photometry files are converted on parsing: IES LM-63 candelas are
multiplied by the candela multiplier and the ballast factor; EULUMDAT values (cd per 1000 lm of
lamp flux) are scaled by the lamp flux of the first lamp set.

A photon's weight is a luminous flux in lm; a sensor's tally divided by its area is an illuminance
in lx. Attenuation coefficients (`absorption_per_m`, `scattering_per_m`) are in 1/m.
"""

from __future__ import annotations

import math

#: Solid angle of the full sphere, sr.
FULL_SPHERE_SR = 4.0 * math.pi

#: Flux of an isotropic point source per candela of intensity, lm/cd (Φ = 4π I).
LUMENS_PER_CANDELA_ISOTROPIC = FULL_SPHERE_SR

#: Degrees → radians.
DEG = math.pi / 180.0

#: Metres per millimetre (EULUMDAT sizes are in mm).
MM = 1e-3

#: Metres per foot (IES LM-63 sizes with units_type 1 are in feet).
FOOT = 0.3048
