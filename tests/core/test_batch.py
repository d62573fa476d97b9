"""Issue 32: ``curveskel batch`` over a library of 10 small generated meshes (every format,
nested folders) and 3 bad inputs, on the process pool and on a 2-worker Dask LocalCluster;
against the single-file command line. The method runs with a coarse Detail Size
(``batch_support.METHOD``) to keep the runs short; the 60-mesh library (shared, held-out and
procedural meshes) is scripts/bench.py --batch's.

The expensive runs are module fixtures, each done once: the reference (``curveskel
skeletonize``'s ``main`` per file, one BLAS thread as the batch's workers), the pool run and
the Dask run of the whole library (the crash and hang inputs armed by the test-hook variable).
No assertion on time: the limits are set far above what a normal asset takes (20 s against
the slowest asset's few seconds here) and only the hanging file reaches them.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import distributed
import pytest

from batch_support import (BATCH, METHOD, METHOD_ARGS, ONE_THREAD, SMALL, make_bad, make_library,
                           read_rows, reference_digests, run_batch, temp_files)
from curveskel_addon.batch.records import skeleton_digest
from curveskel_addon.batch.task import TEST_HOOKS_ENV

HOOKS = {TEST_HOOKS_ENV: "1"}
TIMEOUT = 20                  # seconds; an asset here takes a few seconds at most, the hang forever
N = len(SMALL)                # the good meshes


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """``lib/good/...`` (10 meshes) and ``lib/bad/`` (3 bad inputs); absolute paths."""
    lib = tmp_path_factory.mktemp("batch") / "lib"
    good = [lib / "good" / r for r in make_library(lib / "good", names=SMALL, real=False)]
    bad = [lib / r for r in make_bad(lib)]
    assert len(good) == N and len({p.suffix for p in good}) == 4
    return lib, good, bad


@pytest.fixture(scope="module")
def reference(library, tmp_path_factory):
    """{absolute path: skeleton digest} by the single-file command line."""
    _, good, _ = library
    ref = reference_digests(good, tmp_path_factory.mktemp("reference"))
    assert all(ref.values()), [p for p, d in ref.items() if d is None]
    return {Path(p): d for p, d in ref.items()}


@pytest.fixture(scope="module")
def pool_run(library, tmp_path_factory):
    lib, _, _ = library
    out = tmp_path_factory.mktemp("pool") / "out"
    r = run_batch(lib, "--out", out, "--workers", 2, "--timeout", TIMEOUT, *METHOD_ARGS, env=HOOKS)
    return r, out


@pytest.fixture(scope="module")
def dask_run(library, tmp_path_factory):
    lib, _, _ = library
    out = tmp_path_factory.mktemp("dask") / "out"
    r = run_batch(lib, "--out", out, "--dask", "local:2", "--timeout", TIMEOUT, *METHOD_ARGS,
                  env=HOOKS)
    return r, out


def _json_digests(out: Path, rows) -> dict:
    """{source path: digest of the skeleton JSON on disk} for the rows that are ok."""
    got = {}
    for row in rows:
        if row["status"] == "ok":
            (json_rel,) = [o for o in row["outputs"] if o.endswith(".json")]
            got[Path(row["source"])] = skeleton_digest(json.loads((out / json_rel).read_text()))
    return got


def _check_full_run(r, out, library, reference):
    lib, good, bad = library
    assert r.returncode == 1, r.stderr[-3000:]           # 1: some asset is not ok
    assert "Traceback" not in r.stderr
    rows = read_rows(out)
    assert [row["path"] for row in rows] == sorted(f"{p.relative_to(lib).as_posix()}"
                                                   for p in good + bad)
    by = {row["path"]: row for row in rows}
    # every good mesh: ok, its JSON where the input tree says, equal to the single file's
    for p in good:
        row = by[p.relative_to(lib).as_posix()]
        assert row["status"] == "ok", row
        assert row["outputs"] == [p.relative_to(lib).as_posix() + ".json"]
        assert row["joints"] >= 2 and row["bones"] >= 1 and row["vertices"] > 0
        assert row["sha256"] and len(row["sha256"]) == 64 and row["peak_mb"] > 10
    assert _json_digests(out, rows) == reference
    assert {Path(row["source"]): row["skeleton_sha256"] for row in rows if row["status"] == "ok"} == reference
    # the bad inputs: one row each, with their reason
    assert by["bad/empty.obj"]["status"] == "refused"
    assert by["bad/empty.obj"]["reason"] == "empty.obj contains no vertices"
    assert by["bad/crash.obj"]["status"] == "crashed"
    assert "killed by SIGSEGV" in by["bad/crash.obj"]["reason"]
    assert by["bad/hang.obj"]["status"] == "timeout"
    assert f"time limit of {TIMEOUT} s" in by["bad/hang.obj"]["reason"]
    assert not (out / "bad").exists() or not any((out / "bad").glob("*.json"))
    assert temp_files(out) == []
    # the CSV holds the same rows
    import csv

    with open(out / "results.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [t["path"] for t in table] == [row["path"] for row in rows]
    assert [t["status"] for t in table] == [row["status"] for row in rows]
    assert [int(t["joints"]) for t in table if t["status"] == "ok"] == \
           [row["joints"] for row in rows if row["status"] == "ok"]
    # the summary: counts per status, slowest, refusals by reason
    assert f"{N + 3} of {N + 3} assets" in r.stdout
    assert f"{N} ok, 1 refused, 1 timeout, 1 crashed" in r.stdout
    assert "refused     1 x FILE contains no vertices (bad/empty.obj)" in r.stdout
    assert "slowest     " in r.stdout and f"results     {out / 'results.jsonl'}" in r.stdout
    # progress on stderr, plain lines in a log (not a terminal)
    assert f"progress    {N + 3}/{N + 3} assets (100 %)" in r.stderr and "/min" in r.stderr
    return rows


def test_pool_outputs_equal_the_single_file_command_and_bad_inputs_get_rows(pool_run, library, reference):
    r, out = pool_run
    _check_full_run(r, out, library, reference)
    # the empty file's reason is the command line's own message
    lib, _, _ = library
    one = subprocess.run([sys.executable, str(BATCH.parent / "skeletonize.py"),
                          str(lib / "bad" / "empty.obj")], capture_output=True, text=True, timeout=300)
    reason = {row["path"]: row["reason"] for row in read_rows(out)}["bad/empty.obj"]
    assert one.returncode == 2 and one.stderr == f"error: {reason}\n"


def test_dask_local_cluster_gives_the_pools_outputs_and_report(dask_run, pool_run, library, reference):
    r, out = dask_run
    rows = _check_full_run(r, out, library, reference)
    assert "Dask local:2: 2 workers" in r.stdout
    pool_rows = read_rows(pool_run[1])
    same = ("path", "status", "reason", "sha256", "vertices", "faces", "joints", "bones", "J0",
            "J", "E0", "E", "iterations", "skeleton_sha256", "outputs")
    assert [{k: row[k] for k in same} for row in rows] == [{k: row[k] for k in same} for row in pool_rows]


def test_rerun_computes_nothing_and_keeps_the_table(pool_run, library, tmp_path):
    """A second run with the same settings reuses every output (ok and refused rows); the
    crash and the time-out are tried again (here without the hooks: they are ordinary
    capsules then)."""
    import shutil

    lib, _, _ = library
    out = tmp_path / "out"
    shutil.copytree(pool_run[1], out)            # copy2: the files' times kept
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*.json")}
    first = {row["path"]: row for row in read_rows(out)}
    r = run_batch(lib, "--out", out, "--workers", 2, "--quiet", *METHOD_ARGS)
    assert r.returncode == 1 and r.stdout == "" and r.stderr == ""   # 1: empty.obj is refused
    rows = read_rows(out)
    assert len(rows) == N + 3
    for row in rows:
        if first[row["path"]]["status"] in ("ok", "refused"):
            assert row["reused"] is True, row["path"]
            assert row["status"] == first[row["path"]]["status"]
            assert row["skeleton_sha256"] == first[row["path"]]["skeleton_sha256"]
        else:
            assert row["reused"] is False and row["status"] == "ok", row
    after = {p: p.stat().st_mtime_ns for p in out.rglob("*.json") if p in before}
    assert after == before                      # nothing rewritten


def test_one_worker_in_another_order_gives_the_same_skeletons(library, reference, tmp_path):
    """Deterministic: one worker, the assets named by a manifest (reversed) and a glob, and
    the library API."""
    from curveskel_addon.batch import run

    lib, good, _ = library
    subset = good[::3]
    manifest = tmp_path / "list.txt"
    manifest.write_text("# the batch's manifest: a path a line\n\n"
                        + "".join(f"{os.path.relpath(p, tmp_path)}\n" for p in reversed(subset[1:])))
    res = run([manifest, str(subset[0].parent / ("*" + subset[0].suffix))], tmp_path / "out",
              workers=1, timeout=TIMEOUT, params=METHOD)
    got = {Path(row["source"]): row["skeleton_sha256"] for row in res}
    assert set(subset) <= set(got)
    assert {p: got[p] for p in subset} == {p: reference[p] for p in subset}
    assert all(row["status"] == "ok" for row in res)
    assert res == read_rows(tmp_path / "out")     # the table returned is the table written
    assert res.workers_started == 1


def _wait_for(pred, timeout=300.0, what="a condition"):
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def _descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (from /proc)."""
    kids: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d.name))
    out, todo = [], [pid]
    while todo:
        for k in kids.get(todo.pop(), []):
            out.append(k)
            todo.append(k)
    return out


def _gone(pids) -> bool:
    for pid in pids:
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            continue
        if stat.rsplit(")", 1)[1].split()[0] != "Z":
            return False
    return True


@pytest.mark.parametrize("how", ["SIGKILL", "SIGINT"])
def test_interrupted_halfway_then_rerun_computes_each_asset_once(how, library, reference, tmp_path):
    """Killed (SIGKILL: no clean-up at all; the library's folder, stopped once half are written)
    or interrupted (Ctrl-C; the meshes named by a manifest, stopped at a third), then run again:
    every JSON on disk after the stop is reused as it is, every other asset is computed by the
    second run, none is lost; no temporary file is left."""
    if not Path("/proc").is_dir():
        pytest.skip("needs /proc")
    lib, good, _ = library
    if how == "SIGKILL":
        inputs, n, stop_at = lib / "good", N, N // 2
    else:
        inputs, n, stop_at = tmp_path / "list.txt", N, N // 3
        inputs.write_text("".join(f"{p}\n" for p in good[::2] + good[1::2]))
        assert len(inputs.read_text().splitlines()) == n
    out = tmp_path / "out"
    cmd = [sys.executable, str(BATCH), str(inputs), "--out", str(out), "--workers", "2",
           "--timeout", str(TIMEOUT), *METHOD_ARGS]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    jsons = lambda: [p for p in out.rglob("*.json") if ".curveskel-batch" not in p.parts]
    _wait_for(lambda: len(jsons()) >= stop_at or proc.poll() is not None, what=f"{stop_at} outputs")
    assert proc.poll() is None, proc.communicate()
    workers = _descendants(proc.pid)
    assert workers                              # the worker processes at the stop
    proc.send_signal(getattr(signal, how))
    stdout, stderr = proc.communicate(timeout=120)
    _wait_for(lambda: _gone(workers), timeout=60, what="the workers to leave")
    written = {p: p.stat().st_mtime_ns for p in jsons()}
    assert stop_at <= len(written) < n
    if how == "SIGINT":
        assert proc.returncode == 130 and "interrupted" in stderr and "Traceback" not in stderr
        done = read_rows(out)                    # the table of what was done is written
        assert len(done) >= stop_at - 2 and all(row["status"] == "ok" for row in done)
        assert {out / (row["path"] + ".json") for row in done} == set(written)   # a row each
        assert f"of {n} assets" in stdout and "assets not run" in stdout
        assert temp_files(out) == []
    else:
        assert proc.returncode == -signal.SIGKILL

    r = run_batch(inputs, "--out", out, "--workers", 2, "--timeout", TIMEOUT, *METHOD_ARGS)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = read_rows(out)
    assert len(rows) == n and all(row["status"] == "ok" for row in rows)
    reused = {out / (row["path"] + ".json") for row in rows if row["reused"]}
    assert reused == set(written)               # nothing computed twice
    assert {p: p.stat().st_mtime_ns for p in written} == written
    assert _json_digests(out, rows) == {p: d for p, d in reference.items()
                                        if p in {Path(row["source"]) for row in rows}}
    assert temp_files(out) == []                # a killed run's temporary files are swept


def test_a_dask_worker_killed_mid_batch_has_its_task_retried_elsewhere(library, reference, tmp_path):
    from curveskel_addon.batch import run

    lib, good, _ = library
    subset = good
    out = tmp_path / "out"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        pids = client.run(os.getpid)
        result, error = [], []

        def batch():
            try:
                result.append(run(subset, out, client=client, timeout=TIMEOUT, params=METHOD))
            except BaseException as exc:   # shown by the assertion below
                error.append(exc)

        t = threading.Thread(target=batch)
        t.start()
        _wait_for(lambda: len([p for p in out.rglob("*.json") if ".curveskel-batch" not in p.parts]) >= 4
                  or not t.is_alive(), what="4 outputs")
        victim = sorted(pids.values())[0]
        busy = client.processing()               # tasks on each worker now
        os.kill(victim, signal.SIGKILL)
        t.join(timeout=600)
        assert not error, error
        assert any(busy.values())
        res = result[0]
        after = client.run(os.getpid)
    assert victim not in after.values()         # the nanny started a new worker
    assert len(res) == len(subset) and len({row["path"] for row in res}) == len(subset)
    assert all(row["status"] == "ok" for row in res), [r for r in res if r["status"] != "ok"]
    assert _json_digests(out, res) == {p: reference[p] for p in subset}
    assert read_rows(out) == list(res)
    assert temp_files(out) == []


class _StopWhenMoreAreWritten:
    """A progress stream that, at its first line, waits until ``more`` further skeletons are
    on disk (the cluster goes on finishing assets meanwhile) and then raises
    KeyboardInterrupt: Ctrl-C with rows finished but not yet taken from the cluster. It waits
    on the files, not on a clock, so a fast or a slow machine stops at the same point."""

    def __init__(self, out: Path, more: int = 1, limit: float = 300.0):
        self.out, self.more, self.limit, self.fired = out, more, limit, False

    def _written(self) -> int:
        return sum(1 for p in self.out.rglob("*.json") if ".curveskel-batch" not in p.parts)

    def isatty(self) -> bool:
        return False

    def write(self, text: str) -> None:
        if not self.fired:
            self.fired = True
            start, t0 = self._written(), time.monotonic()
            while self._written() < start + self.more and time.monotonic() - t0 < self.limit:
                time.sleep(0.02)
            raise KeyboardInterrupt

    def flush(self) -> None:
        pass


def test_a_dask_batch_stopped_keeps_a_row_for_every_skeleton_written(library, reference, tmp_path):
    """Ctrl-C on Dask: the tasks that finished while the batch was stopping have their rows in
    the table (their files are on disk), the running ones are stopped; nothing is half-written
    and a rerun reuses exactly what was written."""
    from curveskel_addon.batch import BatchInterrupted, run

    _, good, _ = library
    out = tmp_path / "out"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        with pytest.raises(BatchInterrupted) as info:
            run(good, out, client=client, timeout=TIMEOUT, params=METHOD, progress=True,
                stream=_StopWhenMoreAreWritten(out))
    done = info.value.results
    written = {p: p.stat().st_mtime_ns for p in out.rglob("*.json") if ".curveskel-batch" not in p.parts}
    assert len(written) >= 2 and len(done) < N             # more than the first row, not all
    assert {out / (row["path"] + ".json") for row in done} == set(written)
    assert all(row["status"] == "ok" for row in done) and read_rows(out) == list(done)
    assert temp_files(out) == []
    again = run(good, out, workers=2, timeout=TIMEOUT, params=METHOD)
    assert {out / (row["path"] + ".json") for row in again if row["reused"]} == set(written)
    assert {p: p.stat().st_mtime_ns for p in written} == written
    assert _json_digests(out, again) == {p: reference[p] for p in good}


def test_memory_limit_kills_a_runaway_and_the_rest_runs(library, tmp_path, monkeypatch):
    from curveskel_addon.batch import run

    lib, good, _ = library
    hog = tmp_path / "in" / "hog.obj"
    hog.parent.mkdir()
    body = (lib / "bad" / "crash.obj").read_text().split("\n", 1)[1]
    # comment lines make it the largest file: it runs first, the good one after on a new worker
    hog.write_text("# curveskel-batch-test: memory\n" + "# padding\n" * 100_000 + body)
    monkeypatch.setenv(TEST_HOOKS_ENV, "1")
    res = run([hog, good[0]], tmp_path / "out", workers=1, memory_limit="400M", timeout=TIMEOUT,
              params=METHOD)
    by = {Path(row["source"]).name: row for row in res}
    assert by["hog.obj"]["status"] == "memory"
    assert "memory limit of 400 MiB" in by["hog.obj"]["reason"]
    assert by["hog.obj"]["peak_mb"] > 400
    assert by[good[0].name]["status"] == "ok"
    assert res.workers_started == 2              # a new worker after the kill
    assert res.counts() == {"memory": 1, "ok": 1}


def test_changed_input_settings_or_output_are_computed_again(library, tmp_path):
    from curveskel_addon.batch import run

    _, good, _ = library
    src = tmp_path / "in"
    src.mkdir()
    a, b, c = [src / p.name for p in [p for p in good if p.suffix == ".obj"][:3]]
    for p in good:
        if src / p.name in (a, b, c):
            (src / p.name).write_bytes(p.read_bytes())
    out = tmp_path / "out"
    first = run(src, out, workers=2, params=METHOD)
    assert [r["reused"] for r in first] == [False] * 3
    assert [r["reused"] for r in run(src, out, workers=2, params=METHOD)] == [True] * 3
    with open(a, "a") as fh:                     # other bytes, the same mesh: computed again
        fh.write("# edited\n")
    (out / (b.name + ".json")).unlink()          # an output removed: computed again
    again = run(src, out, workers=2, params=METHOD)
    assert {r["path"]: r["reused"] for r in again} == {a.name: False, b.name: False, c.name: True}
    assert [r["skeleton_sha256"] for r in again] == [r["skeleton_sha256"] for r in first]
    # other settings: everything again, and the outputs follow the settings
    other = run(src, out, workers=2, params={"spacing": 0.2})
    assert [r["reused"] for r in other] == [False] * 3
    assert all(json.loads((out / (r["path"] + ".json")).read_text())["meta"]["params"]["spacing"] == 0.2
               for r in other)


def test_inputs_folders_globs_manifests_and_missing_files(tmp_path):
    from curveskel_addon.batch.inputs import collect
    from curveskel_addon.core import CurveSkelError

    lib = tmp_path / "lib"
    for rel in ("a.obj", "sub/b.OFF", "sub/deep/c.ply", "sub/notes.md", ".git/x.obj", "sub/.d.stl"):
        (lib / rel).parent.mkdir(parents=True, exist_ok=True)
        (lib / rel).write_text("x")
    other = tmp_path / "other" / "d.stl"
    other.parent.mkdir()
    other.write_text("x")
    manifest = tmp_path / "other" / "list.lst"
    manifest.write_text("# comment\n d.stl \n\n../lib/a.obj\nmissing.obj\n../lib/sub/notes.md\n")
    got = collect([lib, str(lib / "sub" / "*"), manifest], exclude=lib / "out")
    # one asset per file (the folder and the glob name b.OFF twice), hidden files skipped,
    # paths from the common folder; the manifest's missing and unsupported files are assets
    # (each gets a row saying what is wrong)
    assert got.root == tmp_path
    assert [a.rel for a in got.assets] == ["lib/a.obj", "lib/sub/b.OFF", "lib/sub/deep/c.ply",
                                           "lib/sub/notes.md", "other/d.stl", "other/missing.obj"]
    assert [a.size for a in got.assets][-1] == -1
    assert got.ignored == 2                      # notes.md in the folder and in the glob
    assert [a.rel for a in collect([lib / "sub"]).assets] == ["b.OFF", "deep/c.ply"]
    for bad, msg in (([tmp_path / "nope"], "no such file or folder"),
                     ([str(tmp_path / "*.xyz")], "matches no file"),
                     ([lib / "sub" / "notes.md"], None)):
        if msg is None:
            assert [a.rel for a in collect(bad).assets] == ["notes.md"]
        else:
            with pytest.raises(CurveSkelError, match=msg):
                collect(bad)
    with pytest.raises(CurveSkelError, match="is not inside the root"):
        collect([lib, other], root=lib)


def test_missing_and_unsupported_files_get_a_row(tmp_path):
    from curveskel_addon.batch import run

    (tmp_path / "list.txt").write_text("gone.obj\nnotes.fbx\n")
    (tmp_path / "notes.fbx").write_text("x")
    res = run(tmp_path / "list.txt", tmp_path / "out", workers=1)
    assert [(r["path"], r["status"], r["reason"]) for r in res] == [
        ("gone.obj", "refused", "no such mesh file: gone.obj"),
        ("notes.fbx", "refused", "unsupported mesh format '.fbx': use one of .obj, .ply, .stl, .off")]


@pytest.mark.parametrize("args, message", [
    (["--bind"], "--bind needs an output"),
    (["--workers", "0"], "--workers 0: needs at least 1"),
    (["--dask", "local:zero"], "local:N needs a number of workers"),
    (["--memory-limit", "lots"], "--memory-limit 'lots'"),
    (["--spacing", "-1"], "spacing"),
    (["--workers", "2", "--dask", "local:2"], "not --workers"),
    (["--timeout", "-1"], "--timeout -1: must be positive"),
    (["--restart-every", "-2"], "--restart-every -2"),
    (["s3://bucket/assets"], "s3://bucket/assets: URLs are not supported"),
    (["--out", "gs://bucket/out"], "gs://bucket/out: URLs are not supported"),
])
def test_bad_arguments_give_one_line_and_exit_2(tmp_path, args, message):
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\n")
    r = run_batch(mesh, "--out", tmp_path / "out", *args, cwd=tmp_path)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert r.stderr.startswith("error:") and message in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_out_is_a_file_or_in_use_by_another_batch(tmp_path):
    from curveskel_addon.batch import run
    from curveskel_addon.batch.driver import _Lock
    from curveskel_addon.core import CurveSkelError

    mesh = tmp_path / "m.obj"
    mesh.write_text("")
    (tmp_path / "file").write_text("x")
    r = run_batch(mesh, "--out", tmp_path / "file")
    assert r.returncode == 2 and "is a file, not a folder" in r.stderr
    out = tmp_path / "out"
    with _Lock(out):
        with pytest.raises(CurveSkelError, match=f"another batch is writing into {out} "
                                                 rf"\(process {os.getpid()}\)"):
            run(mesh, out, workers=1)
    assert [r["status"] for r in run(mesh, out, workers=1)] == ["refused"]    # lock released


def test_summary_groups_refusals_and_names_the_slowest():
    from curveskel_addon.batch.report import summary

    rows = [{"path": f"p{i}.obj", "status": "refused", "reason": f"p{i}.obj line {i}: 'x' is not a number"}
            for i in range(4)]
    rows += [{"path": "e.obj", "status": "refused", "reason": "e.obj contains no vertices"},
             {"path": "s.obj", "status": "ok", "seconds": 9.0},
             {"path": "f.obj", "status": "ok", "seconds": 1.0},
             {"path": "r.obj", "status": "ok", "seconds": 50.0, "reused": True},
             {"path": "t.obj", "status": "timeout", "reason": "exceeded the time limit of 5 s: killed"}]
    text = summary(rows, total=10, seconds=60.0, workers="2 worker processes", slowest=2)
    lines = text.splitlines()
    assert lines[0] == ("batch       9 of 10 assets in 60.0 s, 2 worker processes, 8.0 computed/min: "
                        "3 ok (1 reused), 5 refused, 1 timeout")
    assert lines[1] == "slowest     s.obj 9.0 s, f.obj 1.0 s"      # reused ones were not run
    assert lines[2] == "refused     4 x FILE line N: 'x' is not a number (p0.obj, p1.obj, p2.obj, ...)"
    assert lines[3] == "refused     1 x FILE contains no vertices (e.obj)"
    assert lines[4] == "timeout     t.obj: exceeded the time limit of 5 s: killed"


def test_progress_lines_in_a_log_and_nothing_when_quiet():
    import io

    from curveskel_addon.batch.bar import BatchProgress

    log = io.StringIO()
    p = BatchProgress(20, stream=log, tty=False)
    for i in range(20):
        p.update({"status": "ok" if i % 7 else "refused"})
    lines = log.getvalue().splitlines()
    assert len(lines) == 10                      # one a tenth of the batch, not one an asset
    assert lines[0].startswith("progress    2/20 assets (10 %), ") and "/min, ETA " in lines[0]
    assert lines[-1].startswith("progress    20/20 assets (100 %), ") and lines[-1].endswith("done, 3 not ok")
    quiet = io.StringIO()
    q = BatchProgress(20, stream=quiet, enabled=False)
    for i in range(20):
        q.update({"status": "ok"})
    assert quiet.getvalue() == "" and q.done == 20


def test_curveskel_lists_batch_and_nothing_imports_dask_until_a_dask_run(tmp_path):
    code = ("import sys; sys.path.insert(0, sys.argv[1]);"
            "import curveskel_addon, curveskel_addon.batch, curveskel_addon.cli.batch;"
            "from curveskel_addon.batch import run;"
            "run([sys.argv[2]], sys.argv[3], workers=1);"
            "print(sorted(m for m in ('dask', 'distributed', 'tqdm', 'bpy') if m in sys.modules))")
    mesh = tmp_path / "m.obj"
    mesh.write_text("")
    root = Path(__file__).resolve().parents[2]
    r = subprocess.run([sys.executable, "-c", code, str(root), str(mesh), str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"
    h = subprocess.run([sys.executable, "-m", "curveskel_addon.cli", "--help"], cwd=root,
                       capture_output=True, text=True, timeout=120)
    assert "  batch " in h.stdout
    # the extension bundles no dask, distributed or tqdm wheel
    manifest = (root / "blender_manifest.toml").read_text()
    assert not any(name in manifest for name in ("dask", "distributed", "tqdm"))


def test_quality_measures_in_the_json_the_row_and_the_csv(library, tmp_path):
    """--quality: the JSON's meta is the single-file command's with --quality; the row holds
    the measures, the CSV one column each."""
    import csv

    from curveskel_addon.batch import run

    _, good, _ = library
    mesh = next(p for p in good if p.name.startswith("capsule-8x8"))
    res = run(mesh, tmp_path / "out", workers=1, quality=True, params=METHOD)
    (row,) = res
    one = tmp_path / "one.json"
    r = subprocess.run([sys.executable, str(BATCH.parent / "skeletonize.py"), str(mesh), "--quality",
                        "--json", str(one), "--quiet", *METHOD_ARGS], capture_output=True, text=True,
                       timeout=300, env={**os.environ, **ONE_THREAD})
    assert r.returncode == 0, r.stderr
    doc = json.loads(one.read_text())
    assert row["skeleton_sha256"] == skeleton_digest(doc)
    clockless = lambda q: {k: v for k, v in q.items() if k != "measure_seconds"}
    assert clockless(row["quality"]) == clockless(doc["meta"]["quality"]) and len(row["quality"]) >= 3
    with open(tmp_path / "out" / "results.csv", newline="") as fh:
        (line,) = list(csv.DictReader(fh))
    flat = {k: v for k, v in doc["meta"]["quality"].items() if not isinstance(v, dict)}
    for k, v in flat.items():
        assert line[f"quality.{k}"] == str(v)
