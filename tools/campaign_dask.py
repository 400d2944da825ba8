#!/usr/bin/env python3
"""A campaign of `autopilot batch` runs on a Dask cluster.

One Dask task per shard: it runs the `autopilot` binary (or its container image) for
`batch --shard K/N` in a scratch directory on whichever worker Dask gives it, and returns the
shard's CSV and manifest; the runner keeps them in OUT/shards/ and, once every shard is in, joins
them with `autopilot batch merge` into OUT/campaign.csv: the rows the campaign flown whole on one
machine writes, byte for byte.

Dask schedules and retries; the runner only submits and collects. A shard whose process ends
in error is run again by Dask (`retries`), and one whose worker dies is given to another worker by
the scheduler (`allowed-failures`, set to --retries for a cluster the runner starts): each shard
tells the scheduler when it begins, so the runner says which shard began again. A shard still
failing after that is reported with its reason and the runner exits 1 without merging; the shards
done stay in OUT/shards/, and `--only K,K` flies the rest later.

    tools/campaign_dask.py --workers 2 -- --runs 2000 --seed 7 --params-dir params
    tools/campaign_dask.py --scheduler tcp://10.0.0.5:8786 --image autopilot:latest -- --runs 20000

Without --scheduler it starts a LocalCluster on this machine (loopback only), one worker
process per --workers, one thread each. Everything after `--` is `autopilot batch`'s campaign
flags; --shard, --jobs and -o are the runner's.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import dask
from distributed import Client, LocalCluster, as_completed

# What a task runs: the binary by path, or a container image through a runtime.
Launcher = dict
# The scheduler's event topic on which each shard says it begins.
TOPIC = "autopilot-shard-begins"


def die_with(parent: int):
    """What the shard's process runs before it starts (`preexec_fn`): die when the worker that
    started it dies (Linux's PR_SET_PDEATHSIG), so a killed worker leaves no orphan flying on;
    at once if it already has. `prctl` is looked up here, before the fork: nothing that may
    take a lock runs between fork and exec."""
    if not sys.platform.startswith("linux"):
        return None
    prctl = ctypes.CDLL(None, use_errno=True).prctl

    def preexec() -> None:
        prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        if os.getppid() != parent:
            os._exit(1)

    return preexec


def command(launcher: Launcher, workdir: str) -> tuple[list[str], str]:
    """The command line that runs `autopilot` with `workdir` for its files, and the name
    `workdir` has inside it (the directory itself, or its mount point in a container)."""
    if launcher.get("image"):
        runtime = launcher.get("runtime", "docker")
        user = f"{os.getuid()}:{os.getgid()}" if hasattr(os, "getuid") else "0:0"
        return [runtime, "run", "--rm", "--user", user, "-v", f"{workdir}:/shards",
                launcher["image"]], "/shards"
    return [launcher["autopilot"]], workdir


def run_shard(launcher: Launcher, batch_args: list[str], index: int, count: int,
              jobs: int) -> dict:
    """Dask task: flies shard `index` of `count` and returns its CSV and manifest (bytes), the
    seconds it took here and the worker's host. Raises with the shard's last words if it fails."""
    import socket

    started = time.monotonic()
    try:
        from distributed import get_worker

        get_worker().log_event(TOPIC, {"index": index})
    except ValueError:  # not on a Dask worker
        pass
    with tempfile.TemporaryDirectory(prefix="autopilot-shard-") as workdir:
        prefix, inside = command(launcher, workdir)
        argv = prefix + ["batch", *batch_args, "--shard", f"{index}/{count}",
                         "--jobs", str(jobs), "-o", inside + "/"]
        proc = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              preexec_fn=die_with(os.getpid()))
        if proc.returncode != 0:
            words = proc.stderr.decode(errors="replace").strip().splitlines()[-3:]
            raise RuntimeError(f"exit {proc.returncode}: {' | '.join(words)}")
        manifests = sorted(Path(workdir).glob("*.json"))
        if len(manifests) != 1:
            raise RuntimeError(f"expected one manifest, found {len(manifests)}")
        manifest = json.loads(manifests[0].read_text())
        csv = manifests[0].with_name(manifest["csv"])
        return {
            "index": index,
            "csv_name": csv.name,
            "csv": csv.read_bytes(),
            "manifest_name": manifests[0].name,
            "manifest": manifests[0].read_bytes(),
            "seconds": time.monotonic() - started,
            "batch_seconds": manifest["wall_time_s"],
            "runs": manifest["runs_done"],
            "host": socket.gethostname(),
        }


def reason(error: BaseException) -> str:
    """A failure in one line: a lost worker says so."""
    if type(error).__name__ == "KilledWorker":
        return "its worker died (KilledWorker)"
    return f"{type(error).__name__}: {error}"


def parse(argv: list[str]) -> tuple[argparse.Namespace, list[str]]:
    if "--" in argv:
        cut = argv.index("--")
        own, batch_args = argv[:cut], argv[cut + 1:]
    else:
        own, batch_args = argv, []
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        usage="%(prog)s [options] -- BATCH_FLAGS...",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scheduler", help="a Dask scheduler's address [default: start a "
                   "LocalCluster here]")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="worker processes of the LocalCluster [default: every CPU]")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--autopilot", default="target/release/autopilot",
                       help="the binary, at this path on every worker [default: %(default)s]")
    where.add_argument("--image", help="a container image whose entry point is autopilot "
                       "(run by --runtime on every worker)")
    p.add_argument("--runtime", default="docker", help="container runtime [default: docker]")
    p.add_argument("--shards", type=int, help="shards [default: four per worker]")
    p.add_argument("--jobs-per-shard", type=int, default=1,
                   help="threads of each shard's batch [default: 1: a worker thread a shard]")
    p.add_argument("--retries", type=int, default=2,
                   help="times a failed shard is submitted again [default: %(default)s]")
    p.add_argument("--only", help="fly only these shards (comma-separated indices), e.g. the "
                   "ones a run before reported failed")
    p.add_argument("--out", type=Path, default=Path("campaign"),
                   help="directory for shards/ and campaign.csv [default: %(default)s]")
    args = p.parse_args(own)
    for flag in ("--shard", "--shard-count", "--jobs", "-o", "--output"):
        if any(a == flag or a.startswith(flag + "=") for a in batch_args):
            p.error(f"{flag} is the runner's: give the campaign's flags only after --")
    if args.workers < 1 or (args.shards is not None and args.shards < 1) or args.retries < 0:
        p.error("--workers and --shards are at least 1, --retries at least 0")
    return args, batch_args


def main(argv: list[str]) -> int:
    args, batch_args = parse(argv)
    launcher: Launcher = ({"image": args.image, "runtime": args.runtime} if args.image
                          else {"autopilot": str(Path(args.autopilot).resolve())})
    if not args.image and not Path(launcher["autopilot"]).is_file():
        print(f"campaign: no autopilot binary at {launcher['autopilot']} (cargo build --release, "
              "or give --autopilot or --image)", file=sys.stderr)
        return 2
    if args.scheduler:
        client, cluster = Client(args.scheduler), None
        threads = sum(w.get("nthreads", 1)
                      for w in client.scheduler_info().get("workers", {}).values()) or 1
    else:
        # A worker's death costs the shard it flew (and any waiting there) a new start
        # elsewhere, at most --retries times.
        dask.config.set({"distributed.scheduler.allowed-failures": args.retries})
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None)
        client = Client(cluster)
        threads = args.workers
    try:
        return fly(args, batch_args, launcher, client, threads)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def fly(args, batch_args, launcher, client, threads) -> int:
    """Flies the campaign's shards on `client`'s cluster, then merges them."""
    count = args.shards or 4 * threads
    wanted = range(count)
    if args.only:
        try:
            wanted = sorted({int(k) for k in args.only.split(",")})
        except ValueError:
            print(f"campaign: --only {args.only!r}: shard indices, comma-separated",
                  file=sys.stderr)
            return 2
        if any(not 0 <= k < count for k in wanted):
            print(f"campaign: --only {args.only}: shards are 0 to {count - 1}", file=sys.stderr)
            return 2
    shards_dir = args.out / "shards"
    shards_dir.mkdir(parents=True, exist_ok=True)
    print(f"campaign: {len(wanted)} of {count} shards on {threads} worker threads "
          f"({client.scheduler.address})", flush=True)

    started = time.monotonic()
    begun: dict[int, int] = {}

    def on_begin(event) -> None:
        k = event[1]["index"]
        begun[k] = begun.get(k, 0) + 1
        if begun[k] > 1:
            print(f"campaign: shard {k}/{count} began again (try {begun[k]}): its last try "
                  "failed or its worker was lost", flush=True)

    client.subscribe_topic(TOPIC, on_begin)
    # Keys unique to this runner: two campaigns may share a scheduler.
    token = uuid.uuid4().hex[:8]
    futures = {client.submit(run_shard, launcher, batch_args, k, count, args.jobs_per_shard,
                             key=f"shard-{k}-of-{count}-{token}", pure=False,
                             retries=args.retries): k
               for k in wanted}
    done, runs, failed, written = 0, 0, {}, []
    task_seconds = batch_seconds = 0.0
    for future in as_completed(futures):
        k = futures[future]
        try:
            shard = future.result()
        except Exception as error:  # a shard's failure, whatever it was, is reported
            failed[k] = reason(error)
            print(f"campaign: shard {k}/{count} failed: {failed[k]}", flush=True)
            continue
        finally:
            future.release()
        for name, data in ((shard["csv_name"], shard["csv"]),
                           (shard["manifest_name"], shard["manifest"])):
            tmp = shards_dir / f".{name}.tmp"
            tmp.write_bytes(data)
            os.replace(tmp, shards_dir / name)
        written.append(shards_dir / shard["manifest_name"])
        done += 1
        runs += shard["runs"]
        task_seconds += shard["seconds"]
        batch_seconds += shard["batch_seconds"]
        wall = time.monotonic() - started
        print(f"campaign: {done}/{len(wanted)} shards, {runs} runs, "
              f"{runs / max(wall, 1e-9):.1f} runs/s, {wall:.1f} s", flush=True)
    wall = time.monotonic() - started
    retries = sum(n - 1 for n in begun.values())
    if failed:
        print(f"campaign: {len(failed)} shards failed after their retries: "
              + "; ".join(f"{k}/{count}: {why}" for k, why in sorted(failed.items()))
              + f". The shards done are in {shards_dir}; fly the rest with --shards {count} "
              + "--only " + ",".join(str(k) for k in sorted(failed)), file=sys.stderr)
        return 1
    # The engine's cost per task: the Dask task's time beyond the batch's own (process start,
    # the shard's files), and the worker threads' time not spent in tasks (scheduling, the
    # tail).
    process = (task_seconds - batch_seconds) / max(done, 1)
    idle = (threads * wall - task_seconds) / max(done, 1)
    print(f"campaign summary: shards={done} runs={runs} workers={threads} retries={retries} "
          f"wall_time_s={wall:.2f} runs_per_s={runs / max(wall, 1e-9):.2f} "
          f"task_overhead_s={process:.3f} idle_per_task_s={idle:.3f}", flush=True)
    if args.only:
        print(f"campaign: merge once every shard is in: autopilot batch merge {shards_dir}",
              flush=True)
        return 0
    # This run's shards by name: whatever else the directory holds stays out.
    out = args.out / "campaign.csv"
    prefix, inside = command(launcher, str(args.out.resolve()))
    merge = prefix + ["batch", "merge", *(f"{inside}/shards/{m.name}" for m in written),
                      "-o", f"{inside}/campaign.csv"]
    print(f"campaign: merging {len(written)} shards into {out}", flush=True)
    status = subprocess.run(merge).returncode
    if status == 0:
        print(f"campaign: {out}", flush=True)
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
