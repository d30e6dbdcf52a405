"""The launch commit criterion's drift allowance against flights: the drift sensitivity is
linear in the wind change, its k-sigma spread matches the spread of flights through change
fields drawn from the site model, and it is far below the one-sense bound it replaced
(docs/MONTE_CARLO.md §9.2)."""

import numpy as np
import pytest

from vega_campaign.wind_environment import change_rms_mps, load_site, sample_profiles
from vega_gnc.controller_table import default_table_path, load_controller_table
from vega_model.wind import WindTable
from vega_sim.batch import fly_batch
from vega_sim.scenario import dump_scenario, load_scenario
from vega_signoff import lcc

pytestmark = pytest.mark.slow

SITE = load_site()
ALT = SITE.fine_altitude_m
SETTINGS = lcc.load_lcc()
BASE = load_scenario("nominal")
TABLE = str(default_table_path())
N = 96                                       # change fields drawn (July, lag 1.5 h)


def test_change_covariance_hand_case():
    c = lcc.change_covariance([0.0, 1000.0, 3000.0], [0.0, 2000.0], [1.0, 3.0], 1000.0)
    # σ = 1, 2, 3 (held above 2 km); ρ = e^0, e^-1, e^-3, e^-2
    e = np.exp
    np.testing.assert_allclose(c, [[1, 2 * e(-1), 3 * e(-3)], [2 * e(-1), 4, 6 * e(-2)],
                                   [3 * e(-3), 6 * e(-2), 9]], rtol=1e-15)
    with pytest.raises(ValueError):
        lcc.change_covariance([0.0], [0.0], [1.0], 0.0)


@pytest.fixture(scope="module")
def flights():
    """The sensitivity, the allowance for July, and N flights of the nominal predicted flight
    through change fields drawn from the site model (and through their values at the nodes
    only), as drift changes from the calm flight."""
    yaml = dump_scenario(BASE)
    nodes, g = lcc.drift_sensitivity(yaml, TABLE, SETTINGS)
    sigma = change_rms_mps(SITE, 7, 5400.0)
    dz = lcc.drift_allowance_m(yaml, TABLE, ALT, sigma, SITE.change_vertical_correlation_m,
                               SETTINGS)
    change = sample_profiles(SITE, 7, n=N, seed=11, lag_s=5400.0).change_mps
    profiles = [WindTable(ALT, np.zeros_like(ALT), "calm")]
    profiles += [WindTable(ALT, change[i], f"change {i}") for i in range(N)]
    profiles += [WindTable(nodes, np.interp(nodes, ALT, change[i]), f"nodes {i}")
                 for i in range(N)]
    table = load_controller_table(TABLE)
    z = []
    for start in range(0, len(profiles), 16):
        batch = [lcc.predicted_scenario(BASE, p, BASE.guidance)
                 for p in profiles[start:start + 16]]
        z += [np.array(r.z_m, dtype=float) for r in fly_batch(batch, table)]
    z = np.array(z)
    linear = np.array([g.T @ np.interp(nodes, ALT, change[i]) for i in range(N)])
    return {"nodes": nodes, "g": g, "sigma": sigma, "dz": dz, "fine": z[1:N + 1] - z[0],
            "at_nodes": z[N + 1:] - z[0], "linear": linear}


def test_sensitivity_is_the_hat_basis_of_the_nodes(flights):
    nodes, g = flights["nodes"], flights["g"]
    assert nodes[0] == 0.0 and nodes[-1] == SETTINGS.drift_top_m
    assert np.all(np.diff(nodes) == SETTINGS.drift_node_spacing_m)
    assert g.shape == (nodes.size, flights["dz"].size) and np.isfinite(g).all()
    assert np.all(g[:, 0] == 0.0)          # nothing has happened at t = 0
    # every node up to 20 km moves the drift by 0.5-2.3 m per m/s at its largest (measured)
    peak = np.abs(g[nodes <= 20_000.0]).max(axis=1)
    assert peak.min() > 0.4 and 2.0 < peak.max() < 3.0, (peak.min(), peak.max())


def test_drift_is_linear_in_a_change_on_the_nodes(flights):
    """Flown through a change field sampled at the nodes (piecewise linear between them), the
    drift change is g·δw within 12 % rms (measured 8.6 %: the rest is the loop's
    nonlinearity at a few m/s)."""
    d, lin = flights["at_nodes"], flights["linear"]
    rel = np.sqrt(np.mean((d - lin) ** 2)) / np.sqrt(np.mean(d ** 2))
    assert rel < 0.12, rel


def test_allowance_is_k_sigma_of_the_flown_spread(flights):
    """Over N change fields drawn from the site model at full resolution (100 m), the sample
    standard deviation of the drift change agrees with sqrt(gᵀCg) = Δz_k/k where the
    allowance is above 30 m: sampling error at N = 96 is ≈ 7 %, so 0.78–1.22 is three of it
    (measured 0.88–0.99: the allowance is slightly conservative)."""
    d, dz = flights["fine"], flights["dz"]
    sd = d.std(axis=0, ddof=1)
    m = dz > 30.0
    assert m.sum() > 5000                  # most of the 100 s flight
    ratio = sd[m] / (dz[m] / SETTINGS.k_sigma)
    assert 0.78 < ratio.min() and ratio.max() < 1.22, (ratio.min(), ratio.max())


def test_allowance_is_far_below_the_one_sense_bound_it_replaced(flights):
    """Revision 1 moved every node by +kσ at once (ρ ≡ 1): 312 m for July; the correlated
    field's k-sigma response is about a third of it (measured 110 m)."""
    g, nodes, dz = flights["g"], flights["nodes"], flights["dz"]
    s = np.interp(nodes, ALT, flights["sigma"])
    one_sense = np.abs(SETTINGS.k_sigma * (g * s[:, None]).sum(axis=0))
    assert 280.0 < one_sense.max() < 340.0
    assert 80.0 < dz.max() < 140.0
    assert dz.max() < 0.5 * one_sense.max()
