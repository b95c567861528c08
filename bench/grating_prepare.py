"""Preparation figures of a grating element (issue 52): time and table bytes of a lamellar 1-D grating solved by
RCWA (inkstone) at 41 wavelengths x 19 polar angles x 2 polarizations. Run:

    PYTHONPATH=. .venv/bin/python bench/grating_prepare.py [orders]

Prints the seconds, the table's bytes (in memory and as its .npz), the orders kept and `cost`'s estimate beside them.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from tracer.elements import grating

BODY = {"type": "grating", "profile": {"shape": "lamellar", "fill": 0.5}, "period_um": 1.0, "depth_um": 0.3,
        "ridge": None, "substrate_ior": 1.5, "wavelengths_nm": [380, 780], "wavelength_count": 41,
        "angles": {"polar_deg": [float(x) for x in np.linspace(0.0, 81.0, 19)], "azimuth_deg": [0.0]},
        "orders": int(sys.argv[1]) if len(sys.argv) > 1 else 10}

if __name__ == "__main__":
    t0 = time.perf_counter()
    table = grating.prepare(BODY)
    seconds = time.perf_counter() - t0
    canon = grating.check(BODY)
    print(f"orders {canon['orders']} ({grating.harmonics(canon)} harmonics): {seconds:.1f} s for "
          f"{41 * 19} points x 2 polarizations ({seconds / (41 * 19) * 1000:.1f} ms a point); estimate "
          f"{grating.cost(canon):.1f} s; table {table.nbytes:,} bytes in memory, {len(table.to_bytes()):,} as npz; "
          f"{len(table.orders)} orders kept")
