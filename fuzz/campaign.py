#!/usr/bin/env python3
"""A fuzzing campaign: every target (or the ones named) until it reaches an execution count or
a coverage plateau, whichever comes first, then a minimized corpus kept in fuzz/corpus/TARGET.

    fuzz/campaign.py                                  # every target, 2 M executions or plateau
    fuzz/campaign.py --jobs 2 --plateau 600 --cap 1800 exr zarr_store

A target stops when it has run --execs inputs, or when its edge coverage ("cov:" in libFuzzer's
output) has not grown for --plateau seconds (a plateau), or at --cap seconds. Seconds are the
fuzzer process's own CPU seconds, so that a target sharing the machine (the runs are niced) is
not declared on a plateau while it was waiting for a core. It starts from the
committed corpus (fuzz/corpus/TARGET, the previous campaign's result), the seeds
(fuzz/seeds/TARGET) and the repository's own files of its format (as fuzz/run.sh), with the
limits of run.sh: 2 GB of memory, 1 s per input (or as fuzz/timeouts.txt says). After each target the corpus is minimized
(libFuzzer's -merge=1) and replaces fuzz/corpus/TARGET, so the next campaign starts where this
one ended. Results go to stdout as a Markdown table and to fuzz/campaign.json (written
atomically). Exit status 1 if any target crashed (inputs in fuzz/artifacts/TARGET).

Build first: `cargo +nightly fuzz build` (AddressSanitizer, release).
"""
import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor

HERE = os.path.dirname(os.path.abspath(__file__))
BIN = os.path.join(HERE, "target", "x86_64-unknown-linux-gnu", "release")
LINE = re.compile(r"^#(\d+)\s+\w+\s+cov: (\d+) ft: (\d+)")
STAT = re.compile(r"^stat::(\w+):\s+(\d+)")
LIMITS = ["-rss_limit_mb=2048", "-malloc_limit_mb=2048", "-print_final_stats=1"]


def read_timeouts():
    """Seconds per input of the targets that need more than 1 s (fuzz/timeouts.txt)."""
    with open(os.path.join(HERE, "timeouts.txt")) as f:
        pairs = [line.split() for line in f if line.strip() and not line.startswith("#")]
    return {t: int(s) for t, s in pairs}


TIMEOUTS = read_timeouts()


TIMEOUT_OVERRIDE = None


def limits(target):
    t = TIMEOUT_OVERRIDE or TIMEOUTS.get(target, 1)
    return LIMITS + [f"-timeout={t}"]


def repo_seeds(target):
    """The repository's own files of a target's format (fuzz/repo-seeds.txt)."""
    root = os.path.dirname(HERE)
    with open(os.path.join(HERE, "repo-seeds.txt")) as f:
        pairs = [line.split() for line in f if line.strip() and not line.startswith("#")]
    return [os.path.join(root, path) for t, path in pairs if t == target]


TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid):
    """User and system CPU seconds of a process so far (0 once it is gone)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / TICK
    except (OSError, IndexError, ValueError):
        return 0.0


def targets():
    out = subprocess.run(["cargo", "+nightly", "fuzz", "list"], cwd=HERE, check=True,
                         capture_output=True, text=True).stdout
    return [t for t in out.split() if t]


def run_target(target, args, log_dir):
    corpus = os.path.join(HERE, "corpus", target)
    seeds = os.path.join(HERE, "seeds", target)
    os.makedirs(corpus, exist_ok=True)
    os.makedirs(seeds, exist_ok=True)
    artifacts = os.path.join(HERE, "artifacts", target) + "/"
    os.makedirs(artifacts, exist_ok=True)
    extra = []
    rs = repo_seeds(target)
    if rs:
        extra.append("-seed_inputs=" + ",".join(rs))
    cmd = ["nice", "-n", str(args.nice), os.path.join(BIN, target), corpus, seeds,
           f"-runs={args.execs}", f"-max_total_time={4 * args.cap}",
           f"-artifact_prefix={artifacts}"] + limits(target) + extra
    log_path = os.path.join(log_dir, f"{target}.log")
    started = time.monotonic()
    state = {"edges": 0, "features": 0, "last_growth": 0.0, "cpu": 0.0, "execs": 0, "stats": {}}
    lock = threading.Lock()
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, cwd=HERE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True, errors="replace")

        def reader():
            for line in proc.stdout:
                log.write(line)
                m = LINE.match(line)
                with lock:
                    if m:
                        execs, edges, feats = int(m[1]), int(m[2]), int(m[3])
                        state["execs"] = max(state["execs"], execs)
                        if edges > state["edges"]:
                            state["edges"] = edges
                            state["last_growth"] = state["cpu"]
                        state["features"] = max(state["features"], feats)
                    s = STAT.match(line)
                    if s:
                        state["stats"][s[1]] = int(s[2])

        t = threading.Thread(target=reader, daemon=True)
        t.start()
        reason = None
        while proc.poll() is None:
            time.sleep(1)
            cpu = cpu_seconds(proc.pid)
            with lock:
                state["cpu"] = max(state["cpu"], cpu)
                quiet = state["cpu"] - state["last_growth"]
            if state["cpu"] >= args.cap or (state["cpu"] >= args.plateau and quiet >= args.plateau):
                reason = "plateau" if quiet >= args.plateau else "cap"
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    proc.kill()
                break
        proc.wait()
        t.join(timeout=10)
    seconds = time.monotonic() - started
    rc = proc.returncode
    execs = state["stats"].get("number_of_executed_units", state["execs"])
    crashed = reason is None and rc != 0
    if reason is None:
        reason = "crash" if crashed else ("executions" if execs >= args.execs else "cap")
    result = {
        "target": target,
        "seconds": round(seconds),
        "cpu_seconds": round(state["cpu"]),
        "executions": execs,
        "edges": state["edges"],
        "features": state["features"],
        "last_new_edge_cpu_s": round(state["last_growth"]),
        "stop": reason,
        "exit_status": rc,
        "peak_rss_mb": state["stats"].get("peak_rss_mb"),
        "log": os.path.relpath(log_path, HERE),
    }
    if not crashed:
        result["corpus_files"] = minimize(target, corpus, seeds, log_dir)
    return result


def minimize(target, corpus, seeds, log_dir):
    """Merges the corpus and the seeds into a minimal set with the same coverage."""
    fresh = corpus + ".min"
    shutil.rmtree(fresh, ignore_errors=True)
    os.makedirs(fresh)
    with open(os.path.join(log_dir, f"{target}.merge.log"), "w") as log:
        rc = subprocess.run([os.path.join(BIN, target), "-merge=1", fresh, corpus, seeds]
                            + limits(target), cwd=HERE, stdout=log, stderr=subprocess.STDOUT).returncode
    if rc != 0 or not os.listdir(fresh):
        shutil.rmtree(fresh, ignore_errors=True)
        return len(os.listdir(corpus))
    old = corpus + ".old"
    shutil.rmtree(old, ignore_errors=True)
    os.rename(corpus, old)
    os.rename(fresh, corpus)
    shutil.rmtree(old)
    return len(os.listdir(corpus))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("targets", nargs="*")
    p.add_argument("--execs", type=int, default=2_000_000)
    p.add_argument("--plateau", type=int, default=600, help="seconds without a new edge")
    p.add_argument("--cap", type=int, default=1800, help="seconds at most per target")
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--nice", type=int, default=19)
    p.add_argument("--timeout", type=int,
                   help="seconds per input for every target, for a machine shared with other "
                        "work (a niced fuzzer waits for the CPU, and libFuzzer's limit is wall "
                        "time); check the corpora for slow inputs afterwards with --check-slow "
                        "on a quiet machine")
    p.add_argument("--check-slow", action="store_true",
                   help="only run every corpus input once with the normal limits (1 s, "
                        "or as fuzz/timeouts.txt says) and report the targets that fail")
    p.add_argument("--out", default=os.path.join(HERE, "campaign.json"))
    args = p.parse_args()
    global TIMEOUT_OVERRIDE
    TIMEOUT_OVERRIDE = args.timeout
    names = args.targets or targets()
    missing = [t for t in names if not os.path.exists(os.path.join(BIN, t))]
    if missing:
        sys.exit(f"error: not built: {', '.join(missing)} (run cargo +nightly fuzz build)")
    log_dir = os.path.join(HERE, "corpus", "logs")
    os.makedirs(log_dir, exist_ok=True)
    if args.check_slow:
        TIMEOUT_OVERRIDE = None
        failed = []
        for t in names:
            corpus = os.path.join(HERE, "corpus", t)
            os.makedirs(corpus, exist_ok=True)
            os.makedirs(os.path.join(HERE, "artifacts", t), exist_ok=True)
            with open(os.path.join(log_dir, f"{t}.check.log"), "w") as log:
                rc = subprocess.run([os.path.join(BIN, t), "-runs=0", corpus,
                                     os.path.join(HERE, "seeds", t),
                                     f"-artifact_prefix={os.path.join(HERE, 'artifacts', t)}/"]
                                    + limits(t), cwd=HERE, stdout=log,
                                    stderr=subprocess.STDOUT).returncode
            n = len(os.listdir(corpus)) if os.path.isdir(corpus) else 0
            print(f"{t}: {n} corpus inputs, {'ok' if rc == 0 else 'FAILED'}", flush=True)
            if rc != 0:
                failed.append(t)
        sys.exit(1 if failed else 0)
    results = []
    print("| target | CPU s (wall s) | executions | edges / features | last new edge (CPU s) | stop | crashes |")
    print("|---|---:|---:|---|---:|---|---:|")
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for r in pool.map(lambda t: run_target(t, args, log_dir), names):
            results.append(r)
            print(f"| {r['target']} | {r['cpu_seconds']} ({r['seconds']}) | {r['executions']:,} | "
                  f"{r['edges']:,} / {r['features']:,} | {r['last_new_edge_cpu_s']} | {r['stop']} | "
                  f"{1 if r['stop'] == 'crash' else 0} |", flush=True)
            tmp = args.out + ".tmp"
            with open(tmp, "w") as f:
                json.dump({"execs": args.execs, "plateau_s": args.plateau, "cap_s": args.cap,
                           "results": results}, f, indent=1)
            os.replace(tmp, args.out)
    sys.exit(1 if any(r["stop"] == "crash" for r in results) else 0)


if __name__ == "__main__":
    main()
