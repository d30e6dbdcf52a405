"""The first grid point's controller flies alone from 0 s, before lift-off velocity, where the
thrust is still 0 (vega_design.structured.PAD_TIMES_S): its design set holds the bending
plants at 0 s too, and step 7 checks 0 s.

The real case: the `vega design` table of design_runs/seed1, tuned with a design set without
the pad plants, tuned its 0.5 s point on 0.5 s plants only; `vega margins --dispersed`
found 16 dispersed loops unstable at 0 s (mode 2 at −25 %, delay +10 ms, |z| ≈ 1.0002) and 32
more missing the bending criterion there. Its 0.5 and 2 s parameter vectors are below, exact.
"""

import json

import numpy as np
import pytest
from vega_model.parameters import default_context
from vega_model.uncertainty import UncertaintySet

from vega_design import corner_repair as R
from vega_loops import margins as M
from vega_design import structured as S
from fixture_tables import STRUCTURED_2026_11_27

SEED1_05 = np.array([float.fromhex(h) for h in (
    '-0x1.c848bf20e87cep-3', '0x1.9ed2b283745aap-4', '-0x1.5c52471a65facp+1',
    '-0x1.9758799fbb26ap+6', '0x1.1eae89a428bb0p+0', '0x1.f08c47d74961ap-3',
    '0x1.ac325ae4bc5dcp-1', '0x1.46390a1b8bce0p-7', '0x1.32eb351b9faecp+0',
    '0x1.4139b43734c42p+0', '0x1.297d93a5ec2d2p-1', '0x1.7cb9397f83a20p-1',
    '0x1.f6f1a99d9c67cp+0', '0x1.ea1ef33979786p-2')])
SEED1_2 = np.array([float.fromhex(h) for h in (
    '-0x1.51a08d2a80744p-2', '0x1.1ff5c9092b70ap-3', '-0x1.44e50fb7b4302p+1',
    '-0x1.c16c9e6321064p+6', '0x1.26ca58ae39608p+0', '0x1.f4dce03b2ba7cp-3',
    '0x1.a0a2168a9f9e4p-1', '0x1.d2385b9cfec28p-7', '0x1.2fb1535a7e0ccp+0',
    '0x1.3e43b496a04dcp-1', '0x1.ee12ad1701254p-2', '0x1.769cacd9d68f0p-1',
    '0x1.ffff6c4737dd4p+0', '0x1.bfe79dcb5164cp-2')])
UNSTABLE_AT_0 = 602       # f1 +15 %, f2 −25 %, shapes +30 % / +50 %, actuator −10 %, delay +10 ms


@pytest.fixture(scope="module")
def context():
    return default_context()


@pytest.fixture(scope="module")
def sets(context):
    uset = UncertaintySet.from_vehicle(context.vehicle)
    return S.design_set(context, 0.5, uset), S.design_set(context, 2.0, uset), uset


@pytest.mark.slow
def test_the_first_grid_point_is_designed_on_the_bending_plants_at_0s(sets):
    first, later, uset = sets
    bending = [d for _, fam, d in S.design_deviations(uset) if fam == "bending"]
    assert S.DEFAULT_ANCHORS_S[0] == 0.5 and S.PAD_TIMES_S == (0.0,)
    assert len(first.labels) == len(later.labels) + len(bending)
    assert int(first.pad.sum()) == len(bending) and not first.pad[:len(later.labels)].any()
    assert all(lab.startswith("t=0 s ") for lab in np.array(first.labels)[first.pad])
    assert first.labels[0] == "nominal" and not later.pad.any()


def _subset(ds, keep):
    """The same design set without the plants of ``keep`` False (for a comparison)."""
    import dataclasses

    idx = np.flatnonzero(keep)
    return dataclasses.replace(
        ds, labels=[ds.labels[i] for i in idx], families=[ds.families[i] for i in idx],
        modes=[ds.modes[i] for i in idx], Gd=ds.Gd[idx], models=[ds.models[i] for i in idx],
        C=[ds.C[i] for i in idx], rigid_mask=ds.rigid_mask[idx], band_masks=ds.band_masks[idx],
        templates=None, pad=ds.pad[idx])


@pytest.mark.slow
def test_the_seed1_point_misses_only_at_0s_and_the_margin_tool_agrees(sets, context):
    first, _, uset = sets
    _, without_pad = S.evaluate(SEED1_05, _subset(first, ~first.pad), detail=True)
    assert not S.misses_requirement(without_pad)           # what its tuning saw: no miss
    _, with_pad = S.evaluate(SEED1_05, first, detail=True)
    assert S.misses_requirement(with_pad)
    assert with_pad["n_unstable"] > 0
    assert all(lab.startswith("t=0 s ") for lab in with_pad["unstable"])
    assert any("bending_frequency_2-0.25" in lab and "delay_s+0.01" in lab
               for lab in with_pad["unstable"])
    # the independent tool at 0 s, the same controller (the first point's, held)
    pair = S._pair_table(context, (0.5, SEED1_05), (2.0, SEED1_2))
    corner = M.dispersed_corners(uset)[UNSTABLE_AT_0]
    p, act, tau = M.corner_plant(context, 0.0, corner)
    row = M.analyse_loop(M.loop_data(pair, context, 0.0), p, act, tau, nyquist=False)
    assert row["n_unstable"] > 0 and 1.0001 < row["max_abs_eig"] < 1.001


@pytest.mark.slow
def test_pad_plants_count_no_slow_mode_penalty(sets):
    """Without thrust the rigid-body poles stay at z = 1 for any controller: the pad plants
    would add a fixed slow-mode penalty (100 × 1e-4 each) that no tuning can remove."""
    first, _, _ = sets
    meta = json.loads(str(np.load(STRUCTURED_2026_11_27)["metadata"]))
    assert meta["grid_times_s"][0] == 0.5
    x = np.array(meta["parameters_per_grid_time"][0])
    _, d = S.evaluate(x, first, detail=True)
    assert d["n_unstable"] == 0 and not S.misses_requirement(d)   # the reference table's 0.5 s
    radius = S._closed_loop_radius(first, S.discretise(*S.controller_ss(x, first.omega_modes),
                                                       first.dt_s))
    assert np.all(radius[first.pad] > 1.0 - 1e-4)              # the rigid poles at z = 1
    _, flying = S.evaluate(x, _subset(first, ~first.pad), detail=True)
    assert d["penalty_terms"]["slow_modes"] == flying["penalty_terms"]["slow_modes"]


@pytest.mark.slow
def test_step_7_checks_the_times_before_the_first_grid_point(context):
    assert R.interval_times(0.5, 2.0, first=True) == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert R.interval_times(2.0, 4.0, first=True) == [2.0, 2.5, 3.0, 3.5, 4.0]
    assert R.interval_times(0.5, 2.0) == [1.0, 1.5, 2.0]
    done = {0.5: (SEED1_05, None, "given"), 2.0: (SEED1_2, None, "given")}
    rows = R.check_intervals(context, done, (0, UNSTABLE_AT_0), workers=0)
    misses = set().union(*(R.row_misses(r) for rs in rows.values() for r in rs))
    assert (0.0, UNSTABLE_AT_0, "stable") in misses
    assert {m[0] for m in misses} == {0.0}             # 0.5–2 s: no miss at these corners
