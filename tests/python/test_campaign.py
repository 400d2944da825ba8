"""Campaigns beyond one machine: one campaign of `autopilot batch` flown whole, in seven shards
through `--shard`, on a Dask LocalCluster through tools/campaign_dask.py (one of its workers
killed mid-shard), and shard by shard as the Kubernetes Indexed Job's pods would run it
(deploy/k8s/campaign.yaml's command line in the Dockerfile's entry point): the same CSV every
time, byte for byte. Also the CI matrix of docs/campaigns.md, and bad input."""

import json
import os
import re
import signal
import subprocess
import sys
import time

import psutil
import pytest
import yaml

from conftest import ROOT, binary

RUNS, SEED, SHARDS = 200, 7, 7
# Short flights (3 m, a 5 s hover): the campaign's content is not what these tests are about.
CAMPAIGN = ["--runs", str(RUNS), "--seed", str(SEED), "--takeoff", "3", "--hover", "5"]
RUNNER = [sys.executable, str(ROOT / "tools" / "campaign_dask.py")]


def batch(*args, cwd=ROOT, env=None, check=True):
    """`autopilot batch ARGS` from the repository's root (its params/, as the image's WORKDIR
    holds them)."""
    proc = subprocess.run([str(binary("autopilot")), "batch", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)
    if check:
        assert proc.returncode == 0, proc.stderr[-2000:]
    return proc


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """The campaign flown whole on both cores, and in seven shards, all seven at once."""
    tmp = tmp_path_factory.mktemp("campaign")
    whole = tmp / "whole.csv"
    batch(*CAMPAIGN, "--jobs", "2", "-o", str(whole))
    shards = tmp / "shards"
    procs = [subprocess.Popen([str(binary("autopilot")), "batch", *CAMPAIGN, "--shard",
                               f"{k}/{SHARDS}", "--jobs", "1", "-o", f"{shards}/"],
                              cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
             for k in range(SHARDS)]
    for p in procs:
        _, err = p.communicate(timeout=120)
        assert p.returncode == 0, err.decode()[-2000:]
    return tmp, whole, shards


def test_seven_shards_merged_are_the_campaign_flown_whole(flown):
    tmp, whole, shards = flown
    names = sorted(p.name for p in shards.iterdir())
    assert names == sorted([f"batch-{SEED}-shard-{k}-of-{SHARDS}.{e}" for k in range(SHARDS)
                            for e in ("csv", "json")]), names
    merged = tmp / "merged.csv"
    out = batch("merge", str(shards), "-o", str(merged)).stdout
    assert merged.read_bytes() == whole.read_bytes()
    rows = whole.read_text().splitlines()
    assert len(rows) == RUNS + 1 and [r.split(",")[0] for r in rows[1:]] == \
        [str(i) for i in range(RUNS)], "one row a run, in order"
    m, w = (json.loads(p.with_suffix(".json").read_text()) for p in (merged, whole))
    assert m["summary"] == w["summary"] and m["campaign"] == w["campaign"]
    assert m["merged_shards"] == SHARDS and m["runs_done"] == RUNS
    assert w["version"]["git"] not in ("", "unknown"), "the build's commit is recorded"
    shard3 = json.loads((shards / f"batch-{SEED}-shard-3-of-{SHARDS}.json").read_text())
    assert shard3["shard"] == {"index": 3, "count": SHARDS} and shard3["runs_done"] == 29
    # The merge prints the batch's summary lines.
    total = w["summary"]["total"]
    assert f"batch merged: runs={RUNS} landed={total['landed']}" in out, out


def test_the_dask_runner_gives_the_same_campaign_and_a_killed_worker_costs_one_retry(flown):
    """Two workers, seven shards; once a shard's process is flying, its worker is SIGKILLed.
    Dask starts that shard again on a worker, the runner says so, and the campaign merges to
    the same bytes."""
    tmp, whole, _ = flown
    out = tmp / "dask"
    runner = subprocess.Popen(
        RUNNER + ["--workers", "2", "--shards", str(SHARDS), "--autopilot",
                  str(binary("autopilot")), "--out", str(out), "--", *CAMPAIGN],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    victim, deadline = None, time.monotonic() + 60
    while victim is None and time.monotonic() < deadline and runner.poll() is None:
        for p in psutil.Process(runner.pid).children(recursive=True):
            try:
                if p.name() == "autopilot" and "--shard" in (cmdline := p.cmdline()):
                    worker = p.parent()
                    # Stopped first, so the worker dies while its shard is mid-flight.
                    p.suspend()
                    victim = (worker, p, cmdline[cmdline.index("--shard") + 1])
                    break
            except psutil.Error:
                continue
        time.sleep(0.02)
    assert victim, "no shard began"
    worker, shard_process, killed_shard = victim
    os.kill(worker.pid, signal.SIGKILL)
    said, _ = runner.communicate(timeout=120)
    assert runner.returncode == 0, said[-3000:]
    assert not shard_process.is_running() or shard_process.status() == psutil.STATUS_ZOMBIE, \
        "the killed worker's shard process died with it"
    assert f"shard {killed_shard} began again (try 2)" in said, said
    summary = re.search(r"campaign summary: .*", said).group(0)
    assert f"shards={SHARDS} runs={RUNS} workers=2 retries=1" in summary, summary
    print(f"\n{summary}")
    assert (out / "campaign.csv").read_bytes() == whole.read_bytes()


def test_a_shard_that_keeps_failing_is_reported_and_nothing_merged(tmp_path):
    out = tmp_path / "failing"
    proc = subprocess.run(
        RUNNER + ["--workers", "1", "--shards", "2", "--retries", "1", "--autopilot",
                  str(binary("autopilot")), "--out", str(out), "--", "--runs", "4",
                  "--wind-max", "99"],
        cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "2 shards failed after their retries" in proc.stderr, proc.stderr
    assert "--shards 2 --only 0,1" in proc.stderr, proc.stderr
    assert "--wind-max must be within [0, 30] m/s" in proc.stderr, proc.stderr
    assert "began again (try 2)" in proc.stdout
    assert not (out / "campaign.csv").exists()
    bad = subprocess.run(RUNNER + ["--", "--runs", "4", "--jobs", "3"], cwd=ROOT,
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--jobs is the runner's" in bad.stderr, bad.stderr


def k8s_command(name):
    """The command line of the container of the Job `name` in deploy/k8s/: the Dockerfile's
    entry point and the container's args, as the kubelet runs them."""
    dockerfile = (ROOT / "Dockerfile").read_text()
    entry = json.loads(re.findall(r"^ENTRYPOINT (\[.*\])$", dockerfile, re.M)[-1])
    for path in (ROOT / "deploy" / "k8s").glob("*.yaml"):
        for doc in yaml.safe_load_all(path.read_text()):
            if doc and doc["kind"] == "Job" and doc["metadata"]["name"] == name:
                return doc, entry + doc["spec"]["template"]["spec"]["containers"][0]["args"]
    raise AssertionError(f"no Job {name}")


def test_the_kubernetes_jobs_run_the_same_shards_and_merge(flown, tmp_path):
    tmp, whole, shards = flown
    job, command = k8s_command("autopilot-campaign")
    spec = job["spec"]
    assert job["apiVersion"] == "batch/v1" and spec["completionMode"] == "Indexed"
    count = int(command[command.index("--shard-count") + 1])
    assert spec["completions"] == count == SHARDS, "a pod a shard"
    assert spec["template"]["spec"]["restartPolicy"] == "Never", "backoffLimitPerIndex needs it"
    assert spec["backoffLimitPerIndex"] >= 1 and spec["podReplacementPolicy"] == "Failed"
    container = spec["template"]["spec"]["containers"][0]
    mount = container["volumeMounts"][0]["mountPath"]
    assert command[command.index("-o") + 1] == f"{mount}/"
    assert command[0] == "/usr/local/bin/autopilot"
    # Pod 3 as the kubelet runs it: its index in JOB_COMPLETION_INDEX, the volume here.
    here = [str(binary("autopilot"))] + [a.replace(mount, str(tmp_path)) for a in command[1:]]
    env = dict(os.environ, JOB_COMPLETION_INDEX="3")
    proc = subprocess.run(here, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    name = f"batch-{SEED}-shard-3-of-{SHARDS}.csv"
    assert (tmp_path / name).read_bytes() == (shards / name).read_bytes(), \
        "pod 3 flies shard 3 of the campaign"
    # The merge Job over the seven shards.
    merge_job, merge = k8s_command("autopilot-campaign-merge")
    assert merge_job["spec"]["template"]["spec"]["containers"][0]["volumeMounts"][0][
        "mountPath"] == mount
    for f in shards.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    here = [str(binary("autopilot"))] + [a.replace(mount, str(tmp_path)) for a in merge[1:]]
    subprocess.run(here, cwd=ROOT, check=True, capture_output=True, timeout=60)
    assert (tmp_path / "campaign.csv").read_bytes() == whole.read_bytes()


def test_the_ci_matrix_of_the_docs_fans_out_and_merges():
    """The GitHub Actions workflow in docs/campaigns.md: a matrix of shards 0 to N−1, each
    flying --shard INDEX/N, then a job after them all that merges."""
    text = (ROOT / "docs" / "campaigns.md").read_text()
    workflow = yaml.safe_load(re.search(r"```yaml\n(.*?)```", text, re.S).group(1))
    jobs = workflow["jobs"]
    fly = next(j for j in jobs.values() if "strategy" in j)
    shards = fly["strategy"]["matrix"]["shard"]
    runs = "\n".join(s.get("run", "") for s in fly["steps"])
    n = len(shards)
    assert shards == list(range(n)) and n <= 256, "GitHub allows 256 jobs a matrix"
    assert f"--shard ${{{{ matrix.shard }}}}/{n}" in runs, runs
    merge = next(j for j in jobs.values()
                 if any("batch merge" in s.get("run", "") for s in j["steps"]))
    assert merge["needs"] == next(k for k, j in jobs.items() if j is fly), "after every shard"


@pytest.mark.parametrize("args, said", [
    (["--shard", "3/2"], "shard 3 is not one of the 2 shards"),
    (["--shard", "0/0"], "one shard or more"),
    (["--shard-count", "4"], "neither is set"),
])
def test_bad_shards_are_refused_clearly(args, said):
    env = {k: v for k, v in os.environ.items()
           if k not in ("JOB_COMPLETION_INDEX", "AWS_BATCH_JOB_ARRAY_INDEX")}
    proc = batch("--runs", "2", *args, env=env, check=False)
    assert proc.returncode != 0 and said in proc.stderr, proc.stderr


def test_merges_of_two_campaigns_or_a_cut_short_shard_are_refused(flown, tmp_path):
    _, _, shards = flown
    other = tmp_path / "other"
    batch(*CAMPAIGN, "--wind-max", "4", "--shard", f"6/{SHARDS}", "-o", f"{other}/")
    mixed = [str(shards / f"batch-{SEED}-shard-{k}-of-{SHARDS}.json") for k in range(6)]
    proc = batch("merge", *mixed, str(other), "-o", str(tmp_path / "m.csv"), check=False)
    assert proc.returncode != 0 and "two campaigns: wind_max_m_s 5.0 vs 4.0" in proc.stderr, \
        proc.stderr
    cut = tmp_path / "cut"
    cut.mkdir()
    for f in shards.iterdir():
        data = f.read_bytes()
        (cut / f.name).write_bytes(data[:len(data) // 2] if f.name.endswith("-2-of-7.csv")
                                   else data)
    proc = batch("merge", str(cut), "-o", str(tmp_path / "m.csv"), check=False)
    assert proc.returncode != 0 and "cut short: its last line is not whole" in proc.stderr \
        and "-2-of-7.csv" in proc.stderr, proc.stderr
