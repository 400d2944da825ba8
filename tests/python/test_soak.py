"""The soak at CI size (`tools/soak.py`; 24 simulated hours by hand): a tethered hover in
lockstep on the embedded simulator, half a simulated hour, with its logs. Resident memory flat,
no descriptor leaked, the true height within 1 m of the one held while the weather moves the
barometer (`EST_HGT_GPS_TAU`)."""

import sys

from conftest import ROOT, binary

sys.path.insert(0, str(ROOT / "tools"))
from soak import soak  # noqa: E402


def test_half_an_hour_of_hover_keeps_memory_files_and_height(tmp_path):
    r = soak(binary("autopilot").parent, 0.5, tmp_path, seed=2)
    print(r)
    assert r["exit"] == 0, r
    assert r["hover_s"] > 0.45 * 3600, r
    assert r["rss_last_kib"] <= max(r["rss_first_kib"] * 1.1, r["rss_first_kib"] + 2048), r
    assert len(r["fds"]) == 1, f"descriptors over the run: {r['fds']}"
    assert r["worst_height_err_m"] <= 1.0, r
