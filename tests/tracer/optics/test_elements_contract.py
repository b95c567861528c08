"""The thin elements' contract (`tracer.optics.elements.base`: the surface contract, and thin), run for every kind of
`tracer.optics.surfaces.dispatch.KINDS` whose module lives in `tracer/optics/elements/` (elements register beside the
surfaces: one switch at a hit). A kind is checked the moment it is registered.

Same driver and tolerances as `test_surfaces_contract` (`scatter_contract`): specs from the kind's field metadata,
photons from the front and the back at 0°, 45° and 80°, white, unpolarized, linear and circular, N = 20,000 each
through `dispatch.scatter`:

- the white furnace: mean carried weight ≤ 1 + 4σ; f ≥ 0; unit outgoing directions off the sheet;
- thin: `scatter` never changes the medium stack (`med`, `depth`), also for a photon already inside a solid, and
  the kind has no inside (`medium`);
- closed forms: diffuser: R cosine-distributed on the arrival side and T on the far side (T + R, the rest
  absorbed), cos²θ and azimuth uniform in 10 / 8 bins within 4 binomial σ; polarizer: straight on with
  (k1 + k2)/2 for unpolarized and circular light, k1 cos²ψ + k2 sin²ψ for linear light at ψ to its axis (Malus);
  retarder: straight on with T for every state; each lobe within 4σ;
- the switch routes each kind to its own `scatter`.

How these were seen to fail (each a temporary local edit of tracer/, run, then restored; none is committed):
- the diffuser's far-side branch sending T back to the arrival side: its near cosine lobe carries 0.15290 ± 0.00254
  where R = 0 is stated;
- the polarizer passing k1 (not (k1 + k2)/2) to a white photon: 1.00000 ± 0.00354 against the stated 0.5;
- the retarder returning f = 1.05: the furnace at T = 1 reads 1.05 > 1, its straight lobe 1.05 against 1.
"""

from __future__ import annotations

import pytest
from scatter_contract import (
    STATES,
    cases,
    check_closed_form,
    check_contract,
    check_dispatch_routes,
    kinds_in,
)

ELEMENTS = kinds_in("tracer.optics.elements")


def test_elements_are_registered():
    assert ELEMENTS, "no kind of tracer/optics/elements/ is registered in tracer.optics.surfaces.dispatch.KINDS"


@pytest.mark.parametrize("module", ELEMENTS, ids=lambda m: m.NAME)
def test_an_element_is_thin(module):
    """No inside; a photon that crosses or leaves it keeps the medium stack it had, inside a solid too."""
    assert not hasattr(module, "medium") and not hasattr(module, "medium_tables")
    for case in cases([module], STATES[:2]):
        case.med0[0], case.depth0 = case.inst, 1   # some solid the photon is in: the sheet must leave it alone
        out, med = case.run(n=2000)
        assert (out[:, 5] == 1).all() and (med == case.med0).all(), f"{case}: the medium stack changed"


@pytest.mark.parametrize("module", ELEMENTS, ids=lambda m: m.NAME)
def test_scatter_keeps_the_contract_and_conserves_energy(module):
    for case in cases([module]):
        check_contract(case, *case.run())


@pytest.mark.parametrize("module", ELEMENTS, ids=lambda m: m.NAME)
def test_scatter_matches_the_kinds_closed_form(module):
    skipped = [r for case in cases([module]) if (r := check_closed_form(case, *case.run()))]
    if len(skipped) == len(list(cases([module]))):
        pytest.skip(f"{module.NAME}: no closed form ({skipped[0]})")


@pytest.mark.parametrize("module", ELEMENTS, ids=lambda m: m.NAME)
def test_dispatch_routes_the_kind_to_its_own_scatter(module):
    check_dispatch_routes(module)

