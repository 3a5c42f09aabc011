"""The joint planner's shortcuts give exactly what the full computation gives, on real instances.

Oracles (each the computation the shortcut replaces, run here in full):
* a partner's 10-s look (sat_node/scheduler/planner.py ``Planner._first_look_s``) tested block by
  block from the pass index's bound, stopping at the first block that sees one of my GPs, alone and
  with the first blocks of several partners in one FOR test (``_first_looks_s``): the look over
  every sample from the partner's start, as first written (here again);
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bringup.scenario.world import OrbitContext
from orbit_clock.access import for_mask
from sat_node.scheduler import Knowledge, PersistenceView


@pytest.fixture(scope="module")
def dense(paper_scenario):
    sc = paper_scenario.with_overrides(sats=96, hours=1)
    ctx = OrbitContext.from_scenario(sc)
    planner = ctx.planner()
    assert planner.passes is not None
    return ctx, dataclasses.replace(planner.settings, joint_max_partners=1), planner


def _look_as_first_written(planner, name, start, end, mine_km, exact):
    """Planner._first_look_s before the blocks: every sample of the 10-s look at once."""
    coarse = np.append(np.arange(start, end, 10.0), end - planner.settings.dp_step_s)
    seen = for_mask(planner.constellation.track_ecef_km(name, coarse), mine_km, planner.for_deg(name)).any(axis=1)
    if not seen.any():
        return None
    return planner._first_in_for_s(name, coarse, int(np.argmax(seen)), mine_km) if exact else 0.0


def test_the_look_in_blocks_from_the_bound_finds_what_the_whole_look_finds(dense):
    """Every 3rd satellite, every 5 min over the first 50 min: for every partner the pass index keeps
    (onboard: free now; from the ground: free at staggered times), the first time its FOR reaches one
    of my GPs - from the bound and from the start - equals the whole look's, or both see none."""
    ctx, _settings, planner = dense
    names = planner.constellation.names
    seen = unseen = bounded = 0
    for sat in names[::3]:
        for t0 in np.arange(0.0, 3000.0, 300.0):
            know = Knowledge(PersistenceView(ctx.osse, float(t0)))
            ids = planner.candidates(sat, t0, t0 + 600.0)
            if len(ids) == 0:
                continue
            mine = planner.instance(sat, t0, know, window_s=600.0, gp_ids=ids)
            mine_ids = mine.gp_ids[mine.v_first.any(axis=0)]
            if len(mine_ids) == 0:
                continue
            mine_km = planner.gp_ecef_km[mine_ids]
            end = float(t0) + max(600.0, planner.settings.revisit_zero_s)
            for partners in (None, [(n, float(t0) + 120.0 * (j % 6)) for j, n in enumerate(names) if n != sat]):
                partners = partners or [(n, float(t0)) for n in names if n != sat]
                rows = planner._passing(partners, float(t0), end, mine_ids)
                for exact in (True, False):
                    refs = [_look_as_first_written(planner, name, start, end, mine_km, exact)
                            for _order, name, start, _lb in rows]
                    # together (a bounded group's batch: first blocks in one FOR test) and one by one
                    looks = [(name, start, lb) for _order, name, start, lb in rows]
                    assert planner._first_looks_s(looks, end, mine_km, exact) == refs
                    for (_order, name, start, lb), ref in zip(rows, refs):
                        assert planner._first_look_s(name, start, end, mine_km, exact, from_s=lb) == ref
                        assert planner._first_look_s(name, start, end, mine_km, exact) == ref
                for (_order, _name, start, lb), ref in zip(rows, refs):
                    seen += ref is not None
                    unseen += ref is None
                    bounded += lb > start  # the look starts after the partner's start
    assert seen > 50 and unseen > 50 and bounded > 20


def test_for_mask_with_remembered_gp_caps_equals_the_test_of_every_pair(dense):
    """The FOR pre-filter's GP caps (orbit_clock/access.py ``_gp_caps``), remembered per GP set, are
    the ones computed afresh, and the masks made with them over many tracks (the same GP sets asked
    again, as the planners do) equal the test of every (time, GP) pair."""
    from orbit_clock import access

    ctx, _settings, planner = dense
    names = planner.constellation.names
    regions = np.unique(np.asarray(ctx.gps.region_index))
    hits = 0
    for rep in range(3):
        for r in regions:
            gp = np.ascontiguousarray(planner.gp_ecef_km[np.flatnonzero(ctx.gps.region_index == r)])
            key = (gp.tobytes(), 64)
            hits += key in access._GP_CAPS
            for name in names[rep::24]:
                sat = planner.constellation.track_ecef_km(name, np.arange(0.0, 3000.0, 10.0))
                assert np.array_equal(for_mask(sat, gp, 55.0), access._for_mask_all(sat, gp, 55.0))
            cached = access._GP_CAPS[key]
            access._GP_CAPS.pop(key)
            fresh = access._gp_caps(gp, 64)
            assert cached[0] == fresh[0] and all(a.tobytes() == b.tobytes() for a, b in zip(cached[1:], fresh[1:]))
    assert hits >= 2 * len(regions)  # the sets were taken again
