"""The soak at CI size (`tools/soak.py`; 24 simulated hours by hand): a tethered hover in
lockstep on the embedded simulator, half a simulated hour, with its logs in 20 MB parts
(`SDLOG_MAX_SIZE`, 512 MB by default) of which the newest 4 are kept (`SDLOG_ROTATE`). Resident
memory flat, no descriptor leaked, the true height within 1 m of the one held while the weather
moves the barometer (`EST_HGT_GPS_TAU`), the logs within their bound, every part kept readable."""

import sys

from pyulog import ULog

from conftest import ROOT, binary

sys.path.insert(0, str(ROOT / "tools"))
from soak import soak  # noqa: E402


def test_half_an_hour_of_hover_keeps_memory_files_height_and_logs(tmp_path):
    r = soak(binary("autopilot").parent, 0.5, tmp_path, seed=2, settings=("max_size_mb=20",))
    print(r)
    assert r["exit"] == 0, r
    assert r["hover_s"] > 0.45 * 3600, r
    assert r["rss_last_kib"] <= max(r["rss_first_kib"] * 1.1, r["rss_first_kib"] + 2048), r
    assert len(r["fds"]) == 1, f"descriptors over the run: {r['fds']}"
    assert r["worst_height_err_m"] <= 1.0, r
    # About 215 MB written: at most 4 parts of 20 MB (and a chunk) per file kept.
    logs = tmp_path / "logs"
    parts = {p.name: p.stat().st_size for p in logs.iterdir()}
    ulogs = sorted(n for n in parts if n.endswith(".ulg"))
    csvs = sorted(n for n in parts if n.endswith(".csv"))
    assert len(ulogs) == 4 and len(csvs) == 4, sorted(parts)
    assert all(size < 21e6 for size in parts.values()), parts
    assert all(".ulg" not in n or n.count(".") == 2 for n in parts), "the first part removed"
    for name in ulogs:
        ulog = ULog(str(logs / name))
        assert any(d.name == "vehicle_attitude" for d in ulog.data_list), name
    for name in csvs:
        assert (logs / name).read_text().startswith("t_s,mode,"), name
