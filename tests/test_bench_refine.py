"""tools/bench_refine.py: CPU-time figures of LaCAM + LNS, the refined plan validated, the
same plan for the same seed and iteration count."""

from __future__ import annotations

import json

from tool_helpers import load_tool


def load_bench():
    return load_tool("bench_refine")


def test_bench_refine_validates_and_repeats(tmp_path):
    bench = load_bench()
    runs = []
    for k in range(2):
        out = tmp_path / f"r{k}.json"
        assert bench.main(["--agents", "150", "--iterations", "8", "--json", str(out)]) == 0
        runs.append(json.loads(out.read_text()))
    a, b = runs
    assert a["conflicts"] == 0 and a["endpoints_ok"] and a["iterations"] == 8
    assert a["lower_bound"] <= a["soc"] <= a["first_soc"]
    assert (a["first_soc"], a["soc"]) == (b["first_soc"], b["soc"])
    assert all(a[k] >= 0 for k in ("dist_cpu_s", "guide_cpu_s", "lacam_cpu_s", "lns_cpu_s"))
    from warerover_phys.planning.refine import lns as refine

    assert refine.time.monotonic is __import__("time").monotonic  # the clock put back
