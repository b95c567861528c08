"""The surface family's contract (`tracer.optics.surfaces.base`), run for every surface kind registered in
`tracer.optics.surfaces.dispatch.KINDS`: a kind is checked the moment it is registered.

For specs made from the kind's own field metadata, photons arrive at a flat quad from the front and from the back
(a solid's from inside it) at 0°, 45° and 80°, white, unpolarized, linearly and circularly polarized, N = 20,000
each through `dispatch.scatter` (the switch the transport kernel inlines); `scatter_contract` has the driver.

- the white furnace: the mean carried weight (albedo) is at most 1 + 4σ (σ: its standard error), f ≥ 0, finite;
- outgoing directions are unit vectors off the surface, and only a solid's transmitted photon pushes (entering) or
  pops (leaving) the solid on the medium stack; a status the contract names, dim never goes back;
- closed forms (for every state where the kind's value does not depend on it; the dielectric's and a metal's for
  white, unpolarized and circular light, which an interface sees alike): every photon leaves in a lobe the
  kind's docstring states (Lambertian: cosine-distributed on the arrival side with probability ρ; mirror: the
  mirror direction with R, a metal at normal incidence ((n−1)² + k²)/((n+1)² + k²); mix: ρd cosine + ρs mirror;
  dielectric: Fresnel R (exact (Rs + Rp)/2, ((n−1)/(n+1))² at normal incidence, 1 beyond the critical angle) to
  the mirror direction and 1 − R along Snell's refracted one; black: nothing), each lobe's carried weight within
  4σ of its probability (σ: the larger of its standard error and the binomial √(p(1−p)/N)); a cosine lobe's cos²θ
  and azimuth are uniform (density cosθ/π): 10 and 8 equal bins, each within 4 binomial σ;
- the switch routes each kind to its own `scatter` (bit-identical answers).

How these were seen to fail (each a temporary local edit of tracer/, run, then restored; none is committed):
- Lambertian `scatter` returning f = 1.02: the furnace at ρ = 1 reads 1.02000 ± 0 > 1, and its cosine lobe 1.02
  against the stated 1;
- `frames.sample_cosine` with z = 1 − u1 instead of √(1 − u1): Lambertian's and mix's cosine lobes fail the cos²θ
  bins (one bin 34σ off);
- the dielectric's `fresnel_dielectric` returning 0.9 R: its mirror lobe at 80° carries 0.35020 ± 0.00345 against
  Fresnel's 0.38770 (10.9σ);
- the mirror's branch taken out of `dispatch.scatter`: its mirror lobe carries 0 of 0.15, and the routing check
  fails;
- the dielectric pushing `inst + 1` on the medium stack: "a photon entering the solid did not push it".
"""

from __future__ import annotations

import pytest
from scatter_contract import (
    cases,
    check_closed_form,
    check_contract,
    check_dispatch_routes,
    kinds_in,
)

from tracer.optics.surfaces import dispatch

SURFACES = kinds_in("tracer.optics.surfaces")
ELEMENTS = kinds_in("tracer.optics.elements")


def test_the_registry_holds_the_surfaces_and_the_elements():
    """Every registered kind is a surface or an element (and so is run by one of the two contract files); its id is
    its position."""
    assert {m.NAME for m in SURFACES} | {m.NAME for m in ELEMENTS} == {m.NAME for m in dispatch.KINDS}
    assert len(SURFACES) + len(ELEMENTS) == len(dispatch.KINDS) and SURFACES
    for k, m in enumerate(dispatch.KINDS):
        assert dispatch.KIND_OF[m.NAME] == k
        assert callable(m.row) and callable(m.effects) and callable(m.diffuse_only)
        assert callable(m.scatter.py_func)


@pytest.mark.parametrize("module", SURFACES, ids=lambda m: m.NAME)
def test_scatter_keeps_the_contract_and_conserves_energy(module):
    for case in cases([module]):
        check_contract(case, *case.run())


@pytest.mark.parametrize("module", SURFACES, ids=lambda m: m.NAME)
def test_scatter_matches_the_kinds_closed_form(module):
    skipped = [r for case in cases([module]) if (r := check_closed_form(case, *case.run()))]
    if len(skipped) == len(list(cases([module]))):
        pytest.skip(f"{module.NAME}: no closed form ({skipped[0]})")


@pytest.mark.parametrize("module", SURFACES, ids=lambda m: m.NAME)
def test_dispatch_routes_the_kind_to_its_own_scatter(module):
    check_dispatch_routes(module)
