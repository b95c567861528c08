"""Zemax / Radiant "BSDF Data Interchange" files (``.bsdf``, IS-BSDF), read into a `measured_brdf` table.

Why this format: the Imaging Sphere (IS-SA) and other goniophotometers export it, OpticStudio, LightTools and
Speos import it, and its layout is public: R. Rykowski, "BSDF Data Interchange File Format Specification" (Radiant
Imaging, 2008; Zemax knowledge base article 229, now support.zemax.com article 1500005486801, "Zemax Tabular BSDF
data file format"). A file is text::

    # comments
    Source  Measured
    Symmetry  PlaneSymmetrical            (Asymmetrical, Asymmetrical4D: refused, see below)
    SpectralContent  Monochrome           (XYZ: refused)
    ScatterType  BRDF                     (BTDF: refused)
    SampleRotation  1
    0
    AngleOfIncidence  3
    0 30 60
    ScatterAzimuth  5
    0 45 90 135 180
    ScatterRadial  4
    0 10 30 90

    Monochrome
    DataBegin
    TIS 0.72                              (one block per angle of incidence: its total integrated scatter,
    3.689 3.575 2.907 1.2                  then one line per azimuth of one value per radial angle)
    ...
    DataEnd

The scatter angles are centred on the specular direction (the spec's "Definition of coordinate system"): radial 0°
is the direction of specular reflection, increasing outwards; azimuth 0° points from the specular direction
towards the sample's normal and increases counter-clockwise; "PlaneSymmetrical" data are symmetric about the plane
of incidence, so azimuths cover [0°, 180°]. The values are relative: the spec's own example reads 3.7 sr⁻¹ for a
matte sample of TIS 0.72 (a Lambertian one would read 0.23), so each block is scaled here to reflect its TIS (as
Ansys' BSDF converter normalises them). The radial angle is taken as the angle between the outgoing and the specular
direction, as the spec's text defines it.

Resampling: `measured_brdf` tabulates f over (θo, Δφ) cells. Each cell of `THETA_O_EDGES` × `DPHI_EDGES` takes the
mean of the file's value (bilinear in azimuth and radial; 0 past the last radial angle) at 3 × 3 directions spread
over the cell by projected solid angle; each row is then scaled so that its directional albedo is the block's TIS.
A smooth lobe keeps its shape to the cells' resolution (2.5° in θo, 5° in Δφ); a lobe narrower than a cell is
widened to it. Refused, each with a `MaterialError` naming the line and what to do: transmission (BTDF), tristimulus
data, asymmetric or anisotropic samples (more than one rotation), counts that do not match, a TIS outside [0, 1],
negative or non-finite values, a block whose data are all 0 where its TIS is not.
"""

from __future__ import annotations

import math

import numpy as np

from tracer.optics.surfaces.base import MaterialError

THETA_O_EDGES = np.linspace(0.0, 90.0, 37)    # degrees: 2.5° bins of the outgoing polar angle
DPHI_EDGES = np.linspace(0.0, 180.0, 37)      # degrees: 5° bins of the azimuth from the source's side
SUB = 3                                       # directions per cell side averaged in the resampling
HEADS = ("Source", "Symmetry", "SpectralContent", "ScatterType", "SampleRotation", "AngleOfIncidence",
         "ScatterAzimuth", "ScatterRadial")


def is_zemax(text: str) -> bool:
    """Whether `text` opens as a BSDF Data Interchange file (its first word, past comments, names a header)."""
    for line in text[:4096].splitlines():
        words = line.split("#", 1)[0].split()
        if words:
            return words[0] in HEADS
    return False


class _Lines:
    """A file's non-blank lines (line number, words; comments dropped), read in order: each read names the line
    where the file does not hold what the format puts there."""

    def __init__(self, text: str, where: str) -> None:
        lines = [(k, line.split("#", 1)[0].split()) for k, line in enumerate(text.splitlines(), 1)]
        self.lines = [(k, w) for k, w in lines if w]
        self.pos = 0
        self.where = where

    def take(self, label: str) -> list[str]:
        """The words after `label` on the next line, which must open with it."""
        lines, pos, where = self.lines, self.pos, self.where
        if pos >= len(lines) or lines[pos][1][0] != label:
            seen = " ".join(lines[pos][1])[:60] if pos < len(lines) else "the end of the file"
            raise MaterialError(f"{where}: expected a {label!r} line (line {lines[pos][0] if pos < len(lines) else '-'}"
                                f"), got {seen!r}: is this a Zemax BSDF Data Interchange file?")
        self.pos += 1
        return lines[pos][1][1:]

    def numbers(self, n: int, what: str) -> np.ndarray:
        """The next `n` numbers, over as many lines as they take; all finite."""
        where = self.where
        out: list[float] = []
        while len(out) < n and self.pos < len(self.lines):
            k, words = self.lines[self.pos]
            try:
                out += [float(w) for w in words]
            except ValueError:
                raise MaterialError(f"{where}: {what}: expected {n} numbers, got {len(out)} before line {k} "
                                    f"({' '.join(words)[:60]!r}): check the counts in the header") from None
            self.pos += 1
        if len(out) != n:
            raise MaterialError(f"{where}: {what}: expected {n} numbers, got {len(out)}")
        a = np.array(out)
        if not np.all(np.isfinite(a)):
            raise MaterialError(f"{where}: {what} must be finite")
        return a

    def count(self, label: str) -> int:
        """The count ≥ 1 on the next line, which must open with `label`."""
        words = self.take(label)
        if len(words) != 1 or not words[0].isdigit() or int(words[0]) < 1:
            raise MaterialError(f"{self.where}: {label!r} must give a count ≥ 1, got {' '.join(words)!r}")
        return int(words[0])

    def word(self, label: str, allowed: tuple[str, ...], why: str) -> None:
        """A header line `label` whose value must be one of `allowed`; `why` says why the others are not read."""
        words = self.take(label)
        if not words or words[0] not in allowed:
            raise MaterialError(f"{self.where}: {label} {' '.join(words)!r} is not read: {why}")


def parse(text: str, where: str = "table") -> dict:
    """The `measured_brdf` inline table (theta_i_deg, theta_o_deg, dphi_deg, brdf) of a BSDF Data Interchange file;
    `MaterialError` naming the line where it is not one this reader takes (module docstring)."""
    doc = _Lines(text, where)
    aoi, az, radial = _read_header(doc)
    doc.take("Monochrome")
    doc.take("DataBegin")
    blocks, tis = _read_blocks(doc, aoi, az, radial)
    doc.take("DataEnd")
    brdf = np.stack([_resample(float(ti), az, radial, b) for ti, b in zip(aoi, blocks, strict=True)])
    _scale_to_tis(brdf, tis, aoi, where)
    return {"theta_i_deg": aoi.tolist(), "theta_o_deg": THETA_O_EDGES.tolist(), "dphi_deg": DPHI_EDGES.tolist(),
            "brdf": brdf.tolist()}


def _read_header(doc: _Lines) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The header's (angles of incidence, scatter azimuths, scatter radial angles) in degrees, once its kind lines
    say a table `measured_brdf` takes (measured, plane-symmetrical, monochrome reflection, one sample rotation)."""
    where = doc.where
    doc.word("Source", ("Measured",), "the spec knows only 'Measured'")
    doc.word("Symmetry", ("PlaneSymmetrical",), "measured_brdf is isotropic and symmetric about the plane of "
             "incidence; export the sample's PlaneSymmetrical data")
    doc.word("SpectralContent", ("Monochrome",), "export Monochrome (photopic) data; tristimulus files are not read")
    doc.word("ScatterType", ("BRDF",), "measured_brdf reflects; transmission (BTDF) tables are not read")
    if doc.count("SampleRotation") != 1:
        raise MaterialError(f"{where}: more than one SampleRotation is an anisotropic sample, which measured_brdf "
                            f"(isotropic) does not take; export one rotation")
    doc.numbers(1, "the sample rotation")
    aoi = doc.numbers(doc.count("AngleOfIncidence"), "AngleOfIncidence")
    az = doc.numbers(doc.count("ScatterAzimuth"), "ScatterAzimuth")
    radial = doc.numbers(doc.count("ScatterRadial"), "ScatterRadial")
    for name, a, lo, hi in (("AngleOfIncidence", aoi, 0.0, 90.0), ("ScatterAzimuth", az, 0.0, 180.0),
                            ("ScatterRadial", radial, 0.0, 180.0)):
        if np.any(np.diff(a) <= 0) or a[0] < lo or a[-1] > hi or (name == "AngleOfIncidence" and a[-1] >= 90.0):
            raise MaterialError(f"{where}: {name} must be strictly increasing within [{lo:g}, {hi:g}"
                                f"{')' if name == 'AngleOfIncidence' else ']'} degrees, got {a.tolist()}")
    return aoi, az, radial


def _read_blocks(doc: _Lines, aoi: np.ndarray, az: np.ndarray,
                 radial: np.ndarray) -> tuple[list[np.ndarray], list[float]]:
    """Each angle of incidence's (n_az, n_radial) block of relative values (≥ 0) and its TIS (the fraction
    reflected, in [0, 1])."""
    where = doc.where
    blocks, tis = [], []
    for theta_i in aoi:
        words = doc.take("TIS")
        try:
            t = float(words[0]) if len(words) == 1 else math.nan
        except ValueError:
            t = math.nan
        if not 0.0 <= t <= 1.0:
            raise MaterialError(f"{where}: the TIS of angle of incidence {theta_i:g}° must be a number in [0, 1] "
                                f"(the fraction reflected), got {' '.join(words)!r}")
        b = doc.numbers(len(az) * len(radial), f"the data of angle of incidence {theta_i:g}° ({len(az)} azimuths × "
                        f"{len(radial)} radial angles)").reshape(len(az), len(radial))
        if np.any(b < 0.0):
            raise MaterialError(f"{where}: the data of angle of incidence {theta_i:g}° must be ≥ 0")
        blocks.append(b)
        tis.append(t)
    return blocks, tis


def _scale_to_tis(brdf: np.ndarray, tis: list[float], aoi: np.ndarray, where: str) -> None:
    """Scales each row of `brdf` (sr⁻¹, in place; the format's values are relative) so that its directional albedo
    is its block's TIS."""
    w = _cell_weights()
    for i, (row, level) in enumerate(zip(brdf, tis, strict=True)):
        albedo = float((row * w).sum())
        if albedo <= 0.0 and level > 0.0:
            raise MaterialError(f"{where}: the data of angle of incidence {aoi[i]:g}° are 0 over the hemisphere "
                                f"but its TIS is {level:g}")
        brdf[i] = row * (level / albedo) if albedo > 0.0 else row


def _cell_weights() -> np.ndarray:
    """(n_o, n_p) projected solid angle of each cell, both signs of Δφ (as `measured_brdf.Table.cell_weights`)."""
    mu = np.cos(np.radians(THETA_O_EDGES))
    mu[-1] = 0.0
    return np.outer(mu[:-1] ** 2 - mu[1:] ** 2, np.diff(np.radians(DPHI_EDGES)))


def specular_angles(theta_i_deg: float, theta_o, dphi) -> tuple[np.ndarray, np.ndarray]:
    """(radial, azimuth) in degrees of outgoing directions (θo, Δφ in degrees; Δφ = 180 the specular side) about
    the specular direction of incidence θi: radial from it, azimuth from the way towards the normal, in [0, 180]."""
    ti = math.radians(theta_i_deg)
    to, dp = np.broadcast_arrays(np.radians(theta_o), np.radians(dphi))
    out = np.stack([-np.sin(to) * np.cos(dp), np.sin(to) * np.sin(dp), np.cos(to)], axis=-1)
    spec = np.array([math.sin(ti), 0.0, math.cos(ti)])
    towards_normal = np.array([-math.cos(ti), 0.0, math.sin(ti)])   # unit, ⊥ spec; (−1, 0, 0) at normal incidence
    radial = np.degrees(np.arccos(np.clip(out @ spec, -1.0, 1.0)))
    azimuth = np.degrees(np.arctan2(np.abs(out[..., 1]), out @ towards_normal))
    return radial, azimuth


def _resample(theta_i: float, az: np.ndarray, radial: np.ndarray, block: np.ndarray) -> np.ndarray:
    """(n_o, n_p) cell means of the block's values (bilinear in azimuth and radial, 0 past the last radial)."""
    s = (np.arange(SUB) + 0.5) / SUB
    mu2 = np.cos(np.radians(THETA_O_EDGES)) ** 2
    c2 = mu2[:-1, None] + (mu2[1:] - mu2[:-1])[:, None] * s[None, :]           # cos²θo uniform in each bin
    theta_o = np.degrees(np.arccos(np.sqrt(np.clip(c2, 0.0, 1.0))))           # (n_o, SUB)
    dphi = DPHI_EDGES[:-1, None] + np.diff(DPHI_EDGES)[:, None] * s[None, :]  # (n_p, SUB)
    to = theta_o[:, None, :, None]
    dp = dphi[None, :, None, :]
    r, a = specular_angles(theta_i, to, dp)
    values = _bilinear(az, radial, block, a, r)
    return values.mean(axis=(2, 3))


def _bilinear(az: np.ndarray, radial: np.ndarray, block: np.ndarray, a: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The block (n_az, n_radial) at azimuths `a` and radial angles `r` (degrees): bilinear, clamped in azimuth and
    below the first radial angle, 0 beyond the last."""
    def locate(grid: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if len(grid) == 1:
            return np.zeros(x.shape, np.int64), np.zeros(x.shape)
        j = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, len(grid) - 2)
        t = np.clip((x - grid[j]) / (grid[j + 1] - grid[j]), 0.0, 1.0)
        return j, t

    ja, ta = locate(az, a)
    jr, tr = locate(radial, r)
    ka, kr = np.minimum(ja + 1, len(az) - 1), np.minimum(jr + 1, len(radial) - 1)
    v = ((1 - ta) * ((1 - tr) * block[ja, jr] + tr * block[ja, kr])
         + ta * ((1 - tr) * block[ka, jr] + tr * block[ka, kr]))
    return np.where(r <= radial[-1], v, 0.0)


def write(brdf, aoi_deg, azimuth_deg, radial_deg, scale: float = 1.0) -> str:
    """A BSDF Data Interchange text of an analytic BRDF (tests, examples): `brdf(θi_deg, radial_deg, azimuth_deg)`
    → sr⁻¹ (vectorised over the last two), sampled on the grids, each block written × `scale` (the format's values
    are relative) after its TIS, the directional albedo integrated numerically on a fine grid."""
    aoi, az, rad = (np.asarray(x, np.float64) for x in (aoi_deg, azimuth_deg, radial_deg))
    out = ["# written by tracer.optics.surfaces.zemax_bsdf.write", "Source  Measured", "Symmetry  PlaneSymmetrical",
           "SpectralContent  Monochrome", "ScatterType  BRDF", "SampleRotation  1", "0",
           f"AngleOfIncidence  {len(aoi)}", " ".join(f"{x:g}" for x in aoi),
           f"ScatterAzimuth  {len(az)}", " ".join(f"{x:g}" for x in az),
           f"ScatterRadial  {len(rad)}", " ".join(f"{x:g}" for x in rad), "", "Monochrome", "DataBegin"]
    n = 400
    mu2 = (np.arange(n) + 0.5) / n                            # cos²θo midpoints: equal projected solid angle
    th = np.degrees(np.arccos(np.sqrt(mu2)))
    ph = (np.arange(n) + 0.5) / n * 180.0
    for ti in aoi:
        r, a = specular_angles(float(ti), th[:, None], ph[None, :])
        tis = float(np.mean(brdf(float(ti), r, a)) * math.pi)   # ∫ f cosθ dω = π · mean over cos²θ, Δφ
        values = brdf(float(ti), rad[None, :], az[:, None]) * np.ones((len(az), len(rad)))
        out.append(f"TIS {tis:.9g}")
        out += [" ".join(f"{scale * x:.9e}" for x in row) for row in values]
    out.append("DataEnd")
    return "\n".join(out) + "\n"
