"""Issue 31, "Outputs are safe": what the command line does with each kind of path it is told to
write, a closed stdout and a stop signal. Everything happens in a temporary folder (a FIFO and a
symbolic link stand in for devices: the real /dev/null is never touched)."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cli_support import CLI, run_cli, write_capsule_obj

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def mesh_file(tmp_path_factory):
    return write_capsule_obj(tmp_path_factory.mktemp("outputs") / "capsule.obj")


def _refused(r, *words):
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    for w in words:
        assert w in lines[0], lines[0]
    assert r.stdout == ""                               # refused before the run


def _skeleton(path):
    d = json.loads(Path(path).read_text())
    assert d["format"] == "curveskel-skeleton/1"
    return d


# -- paths that are not regular files ------------------------------------------------------------
def test_a_fifo_is_refused_without_waiting_for_a_reader(mesh_file, tmp_path):
    fifo = tmp_path / "out.json"
    os.mkfifo(fifo)
    r = run_cli(mesh_file, "--json", fifo, timeout=60)       # used to hang on the FIFO
    _refused(r, f"--json {fifo}", "it is a FIFO (named pipe), not a regular file")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_a_symlink_to_a_device_like_node_is_refused_and_left_alone(mesh_file, tmp_path):
    """A link to /dev/null as output must never replace the device: a link to a FIFO stands in
    for it here (both are not regular files; os.stat follows the link the same way)."""
    node = tmp_path / "node"
    os.mkfifo(node)
    link = tmp_path / "null.json"
    link.symlink_to(node)
    r = run_cli(mesh_file, "--json", link, timeout=60)
    _refused(r, "it is a FIFO (named pipe) (through a symbolic link), not a regular file")
    assert link.is_symlink() and os.readlink(link) == str(node) and stat.S_ISFIFO(os.stat(node).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["node", "null.json"]


def test_the_device_check_names_a_character_device(tmp_path, monkeypatch):
    """The kind named for a character device (the /dev/null case), with os.stat stubbed: no
    device is created or touched."""
    from types import SimpleNamespace

    from curveskel_addon.cli import outputs
    from curveskel_addon.core import CurveSkelError

    real = os.stat
    fake = os.stat_result((stat.S_IFCHR | 0o666,) + tuple(real(tmp_path))[1:])
    target = tmp_path / "dev-null.json"
    monkeypatch.setattr(outputs.os, "stat", lambda p, *a, **k: fake if Path(p) == target else real(p, *a, **k))
    args = SimpleNamespace(mesh=tmp_path / "m.obj", json=target, glb=None, fbx=None, blend=None, render=None)
    with pytest.raises(CurveSkelError, match="it is a character device, not a regular file"):
        outputs.check_outputs(args)


def test_a_directory_is_refused(mesh_file, tmp_path):
    r = run_cli(mesh_file, "--json", tmp_path)
    _refused(r, "it is a directory, not a regular file")


# -- symbolic links: followed, the link stays -----------------------------------------------------
def test_a_symlink_to_a_file_writes_through_to_its_target(mesh_file, tmp_path):
    real_dir = tmp_path / "real"
    real_dir.mkdir()
    target = real_dir / "skeleton.json"
    target.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    r = run_cli(mesh_file, "--json", link)
    assert r.returncode == 0, r.stderr
    assert link.is_symlink() and os.readlink(link) == str(target)       # still a link ...
    assert _skeleton(target)["joints"]                                  # ... to the new file
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "real"]
    assert sorted(p.name for p in real_dir.iterdir()) == ["skeleton.json"]   # no temporary left


def test_a_dangling_symlink_creates_its_target(mesh_file, tmp_path):
    link = tmp_path / "link.json"
    link.symlink_to(tmp_path / "new.json")
    r = run_cli(mesh_file, "--json", link)
    assert r.returncode == 0, r.stderr
    assert link.is_symlink() and _skeleton(tmp_path / "new.json")


def test_a_symlink_loop_is_one_line(mesh_file, tmp_path):
    loop = tmp_path / "loop.json"
    loop.symlink_to(loop)
    _refused(run_cli(mesh_file, "--json", loop), "loop.json", "symbolic links")


# -- permissions ----------------------------------------------------------------------------------
@pytest.mark.parametrize("mode", [0o644, 0o600, 0o664, 0o640])
def test_the_replaced_file_keeps_its_mode(mesh_file, tmp_path, mode):
    out = tmp_path / "o.json"
    out.write_text("old")
    out.chmod(mode)
    r = run_cli(mesh_file, "--json", out)
    assert r.returncode == 0, r.stderr
    assert stat.S_IMODE(out.stat().st_mode) == mode and _skeleton(out)


def test_a_new_file_gets_the_umask_mode(mesh_file, tmp_path):
    out = tmp_path / "new.json"
    r = subprocess.run(["sh", "-c", f'umask 027 && exec "{sys.executable}" "{CLI}" "{mesh_file}" --json "{out}"'],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert stat.S_IMODE(out.stat().st_mode) == 0o640


@pytest.mark.parametrize("mode", [0o444, 0o400])
def test_a_read_only_file_is_refused_and_kept(mesh_file, tmp_path, mode):
    """Read-only says "keep this": refused (also as root, who could replace it)."""
    out = tmp_path / "o.json"
    out.write_text("old")
    out.chmod(mode)
    r = run_cli(mesh_file, "--json", out)
    _refused(r, f"the file is read-only (mode {mode:03o})", "refusing to replace it")
    assert out.read_text() == "old" and stat.S_IMODE(out.stat().st_mode) == mode


# -- write first, then print -----------------------------------------------------------------------
@pytest.mark.parametrize("unbuffered", [False, True])
def test_a_closed_stdout_loses_no_file_and_keeps_exit_status_0(mesh_file, tmp_path, unbuffered):
    """skeletonize.py ... --json out.json | true: the reader is gone before the summary; with
    PYTHONUNBUFFERED=1 this gave rc 1, 'unexpected BrokenPipeError' and no JSON."""
    out = tmp_path / "o.json"
    env = dict(os.environ)
    env.pop("PYTHONUNBUFFERED", None)
    if unbuffered:
        env["PYTHONUNBUFFERED"] = "1"
    script = f'"{sys.executable}" "{CLI}" "{mesh_file}" --json "{out}" | true; echo "rc=${{PIPESTATUS[0]}}"'
    r = subprocess.run(["bash", "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert r.stdout.strip() == "rc=0", r.stdout + r.stderr
    assert "BrokenPipe" not in r.stderr and "Exception ignored" not in r.stderr
    assert _skeleton(out)["joints"]


def test_the_summary_comes_after_the_file_is_written(mesh_file, tmp_path):
    """The first byte on stdout is read when the JSON is already complete on disk."""
    out = tmp_path / "o.json"
    p = subprocess.Popen([sys.executable, str(CLI), str(mesh_file), "--json", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = p.stdout.read(1)
    written = _skeleton(out)                      # already whole when stdout starts
    rest, err = p.communicate(timeout=300)
    assert p.returncode == 0, err
    assert first == b"m" and written["joints"]


# -- stop signals ----------------------------------------------------------------------------------
#: The command line with the JSON writer slowed down: half a file written, then "saving" on
#: stderr and a wait, so the test signals it while the temporary file exists.
SLOW_SAVE = textwrap.dedent('''
    import sys, time
    sys.path.insert(0, sys.argv[1])
    from curveskel_addon.core import skeleton
    from curveskel_addon.cli import exit_with
    from curveskel_addon.cli.skeletonize import main

    def slow_save(self, path):
        with open(path, "w") as fh:
            fh.write('{"format": "curveskel-skeleton/1", "joints": [')
            fh.flush()
            sys.stderr.write("saving\\n")
            sys.stderr.flush()
            time.sleep(120)

    skeleton.Skeleton.save = slow_save
    exit_with(main(sys.argv[2:]))
''')


@pytest.mark.parametrize("signame, said", [("SIGINT", "interrupted"), ("SIGTERM", "terminated (SIGTERM)"),
                                           ("SIGHUP", "hung up (SIGHUP)")])
def test_a_stop_signal_during_the_write_removes_the_temporary_file(mesh_file, tmp_path, signame, said):
    """SIGTERM during the JSON write left a hidden .o.json.tmp-PID.json; now every stop signal
    cleans up as Ctrl-C does and exits with 128 + its number; the old file is kept."""
    script = tmp_path / "slow.py"
    script.write_text(SLOW_SAVE)
    work = tmp_path / "work"
    work.mkdir()
    out = work / "o.json"
    out.write_text('{"old": true}')
    p = subprocess.Popen([sys.executable, str(script), str(ROOT), str(mesh_file), "--json", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in p.stderr:
        if line.strip() == "saving":
            break
    temps = [q.name for q in work.iterdir() if q.name != "o.json"]
    assert len(temps) == 1 and temps[0].startswith(".o.json.tmp-")      # the write is under way
    sig = getattr(signal, signame)
    p.send_signal(sig)
    rest, err = p.communicate(timeout=60)
    assert p.returncode == 128 + sig, err
    assert err.strip().splitlines()[-1] == said
    assert sorted(q.name for q in work.iterdir()) == ["o.json"]             # no temporary left
    assert json.loads(out.read_text()) == {"old": True}
    assert rest == ""                                                       # no summary


# -- --bind needs an output -------------------------------------------------------------------------
def test_bind_without_an_output_names_the_flags_that_take_it(mesh_file, tmp_path):
    r = run_cli(mesh_file, "--bind", "--json", tmp_path / "o.json")
    _refused(r, "--bind needs an output", "--glb", "--fbx", "--blend")
    assert not (tmp_path / "o.json").exists()
    _refused(run_cli(mesh_file, "--bind"), "--glb OUT.glb, --fbx OUT.fbx or --blend OUT.blend")
