"""Where a density map's features go on its lattice: blue noise by error diffusion, or each site drawn alone.

A density layout keeps a fraction `fill` of its lattice sites, cell by cell of its map. Drawing each site alone (a
Bernoulli trial, ``"placement": "random"``) makes the local count Poisson-like: a window of N sites holds fN ±
sqrt(N f (1 - f)) features, which a backlight's 1-degree meter sees as about ±10 % of its luminance whatever the
density. Error diffusion (``"blue_noise"``, the default) keeps a site where the fill it owes, carried over from its
neighbours, reaches a threshold, and passes the difference on (Floyd and Steinberg, Proc. SID 17, 75 (1976), in
serpentine order; Ulichney, *Digital Halftoning*, MIT Press 1987, ch. 8: the pattern's power spectrum is blue,
without low frequencies). The count in any window then differs from fN by what crossed its edges, not by
sqrt(N): the local variation falls with the window's size as its perimeter over its area.

The threshold is 1/2 jittered by ±`JITTER`/2 from the layout's seed (`tracer.rng`), which breaks the regular worms
error diffusion draws at some fills and lets a seed give another pattern of the same statistics.

Memory: a float32 row of carried error and an int32 row of map columns (8 bytes per site of a row) beside the kept
bits (1/8 byte per site); nothing else per site (`microstructure.density_cost`).
"""

from __future__ import annotations

import numpy as np

from tracer.jit import njit
from tracer.rng import path_key, uniform

PLACEMENTS = ("blue_noise", "random")
#: full width of the threshold's jitter about 1/2 (a fraction of one feature)
JITTER = 0.2
#: Floyd-Steinberg's weights: ahead in the row, behind below, below, ahead below
AHEAD, BEHIND_BELOW, BELOW, AHEAD_BELOW = 7.0 / 16.0, 3.0 / 16.0, 5.0 / 16.0, 1.0 / 16.0


@njit(cache=True, error_model="numpy", _nrt=False)
def _cell(k, n, pitch, size, cells):
    """The map cell (0 … cells - 1) of lattice index k along an axis of n sites: its centre's."""
    c = int((k + 0.5) * pitch / size * cells)
    return min(c, cells - 1)


@njit(cache=True, error_model="numpy")
def diffuse(fill, nu, nv, pitch, su, sv, seed, bits):
    """Kept sites of an nu × nv lattice (rows along v, sites along u, pitch in mm; the map `fill` (rows, cols) over
    su × sv mm) by serpentine error diffusion, into `bits` ((nu nv + 7) // 8 uint8, zero on entry; site j nu + i is
    bit (j nu + i) % 8 of byte (j nu + i) // 8, little-endian as `np.packbits(..., bitorder="little")`). Returns the
    number kept."""
    rows, cols = fill.shape
    col_of = np.empty(nu, np.int32)
    for i in range(nu):
        col_of[i] = _cell(i, nu, pitch, su, cols)
    below = np.zeros(nu + 2, np.float32)   # error owed to the next row, site i at i + 1 (0, nu + 1: off the edges)
    kept = 0
    for j in range(nv):
        frow = _cell(j, nv, pitch, sv, rows)
        forward = j % 2 == 0
        key = path_key(seed, 0, j)
        carry = 0.0            # error owed to the next site of this row
        pending = 0.0          # the previous site's share ahead below: its slot is read (owed) before it is written
        for s in range(nu):
            i = s if forward else nu - 1 - s
            step = 1 if forward else -1
            owed = below[i + 1]
            below[i + 1] = pending
            value = fill[frow, col_of[i]] + carry + owed
            threshold = 0.5 + JITTER * (uniform(key, i) - 0.5)
            e = value
            if value >= threshold:
                site = j * nu + i
                bits[site >> 3] |= np.uint8(1 << (site & 7))
                kept += 1
                e = value - 1.0
            carry = AHEAD * e
            below[i + 1 - step] += BEHIND_BELOW * e
            below[i + 1] += BELOW * e
            pending = AHEAD_BELOW * e
        # the last site's share ahead below falls off the lattice's edge, as its share ahead in the row does
    return kept
