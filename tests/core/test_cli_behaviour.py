"""Issue 31, "A command line that behaves": progress on stderr, --quiet, --version, --seed's
help, the licence; and the ``curveskel`` command's subcommands (issue 32)."""

from __future__ import annotations

import io
import json
import os
import pty
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from cli_support import CLI, run_cli, write_capsule_obj

from curveskel_addon.cli.progress import Progress

ROOT = Path(__file__).resolve().parents[2]
MANIFEST = tomllib.loads((ROOT / "blender_manifest.toml").read_text())


@pytest.fixture(scope="module")
def mesh_file(tmp_path_factory):
    return write_capsule_obj(tmp_path_factory.mktemp("behaves") / "capsule.obj")


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


# -- the progress reporter -----------------------------------------------------------------------
def test_nothing_is_shown_in_the_first_second():
    clock, s = Clock(), io.StringIO()
    p = Progress(s, tty=True, delay=1.0, clock=clock)
    clock.now += 0.5
    p("first_approximation", 1.0)
    p("fit", 0.3)
    p.close()
    assert s.getvalue() == ""


def test_a_terminal_gets_one_line_redrawn_with_the_stage_and_a_bar():
    clock, s = Clock(), io.StringIO()
    p = Progress(s, tty=True, delay=1.0, clock=clock)
    clock.now += 1.5
    p("first_approximation", 1.0)
    clock.now += 0.5
    p("merge", 0.5)
    text = s.getvalue()
    assert "\n" not in text and text.count("\r") == 2
    first, second = text.split("\r")[1:]
    assert first.startswith("first approximation ") and "[" + "#" * 24 + "]" in first and "100%" in first
    assert second.startswith("optimising ") and "[" + "#" * 12 + "-" * 12 + "]" in second
    assert " 50%" in second and "2.0 s" in second
    p.close()
    assert s.getvalue().endswith("\r" + " " * len(second) + "\r")          # cleared at the end


def test_redraws_within_a_stage_are_at_most_ten_a_second():
    clock, s = Clock(), io.StringIO()
    p = Progress(s, tty=True, delay=0.0, clock=clock)
    for k in range(50):                     # 50 stages of the search in 0.25 s
        clock.now += 0.005
        p(("fit", "merge", "prune", "split", "contract")[k % 5], k / 50)
    # the search's stages are one stage on the bar: redrawn at 0, 0.1 and 0.2 s only
    assert s.getvalue().count("\r") == 3


def test_a_log_gets_one_plain_line_per_stage():
    clock, s = Clock(), io.StringIO()
    p = Progress(s, tty=False, delay=1.0, clock=clock)
    p("read", 0.0)                                          # before the delay: not shown
    clock.now += 1.2
    for k in range(6):                                      # the search: one line for all of it
        p(("initialise", "fit", "merge", "fit", "prune", "done")[k], k / 5)
    clock.now += 0.3
    p("write", 0.0)
    p.close()
    assert s.getvalue() == ("progress    optimising (1.2 s)\n"
                            "progress    writing (1.5 s)\n")


def test_a_log_gets_no_line_while_the_mesh_is_read():
    """A slow start (a loaded machine) must not put a progress line before a bad file's error."""
    clock, s = Clock(), io.StringIO()
    p = Progress(s, tty=False, delay=1.0, clock=clock)
    clock.now += 3.0
    p("read", 0.0)
    assert s.getvalue() == ""
    p("first_approximation", 1.0)
    assert s.getvalue() == "progress    first approximation (3.0 s)\n"


def test_a_bad_file_is_the_only_line_even_with_progress_at_once(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    r = run_cli(path, env={**os.environ, "CURVESKEL_PROGRESS_DELAY": "0"})
    assert r.returncode == 2
    assert r.stderr == "error: the mesh has no faces: curveskel needs a surface, not a point cloud\n"


def test_quiet_shows_nothing_and_a_broken_stream_stops_nothing():
    clock = Clock()
    q = io.StringIO()
    p = Progress(q, enabled=False, tty=True, delay=0.0, clock=clock)
    p("fit", 0.5)
    assert q.getvalue() == ""

    class Broken(io.StringIO):
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

    b = Progress(Broken(), tty=True, delay=0.0, clock=clock)
    b("fit", 0.5)                        # no exception: the run goes on, silently
    assert not b.enabled


# -- the progress of a real run ---------------------------------------------------------------------
def test_a_run_on_a_terminal_draws_the_bar_on_stderr_only(mesh_file, tmp_path):
    """stderr a pseudo-terminal, the delay 0 (CURVESKEL_PROGRESS_DELAY): the stages' names and
    a bar on stderr, redrawn with \\r and cleared; stdout (a pipe) holds only the summary."""
    master, slave = pty.openpty()
    env = {**os.environ, "CURVESKEL_PROGRESS_DELAY": "0"}
    p = subprocess.Popen([sys.executable, str(CLI), str(mesh_file), "--json", str(tmp_path / "o.json")],
                         stdout=subprocess.PIPE, stderr=slave, env=env)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:                     # EIO: the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    out, _ = p.communicate(timeout=300)
    os.close(master)
    err = b"".join(chunks).decode()
    assert p.returncode == 0, err
    for stage in ("reading the mesh", "first approximation", "optimising", "writing"):
        assert "\r" + stage in err, (stage, err)
    assert "[" + "#" * 24 + "]" in err and "\n" not in err.replace("\r\n", "\n").strip("\n")
    assert "progress" not in out.decode() and out.decode().startswith("mesh ")


def test_a_run_into_a_log_gets_plain_lines(mesh_file):
    r = run_cli(mesh_file, env={**os.environ, "CURVESKEL_PROGRESS_DELAY": "0"})
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    assert [ln.split("(")[0].split(None, 1)[1].strip() for ln in lines] == [
        "first approximation", "optimising"]
    assert all(ln.startswith("progress    ") and "\r" not in ln for ln in lines)


def test_quiet_prints_nothing_but_writes_the_file(mesh_file, tmp_path):
    out = tmp_path / "o.json"
    r = run_cli(mesh_file, "--json", out, "--quiet", env={**os.environ, "CURVESKEL_PROGRESS_DELAY": "0"})
    assert r.returncode == 0 and r.stdout == "" and r.stderr == ""
    assert json.loads(out.read_text())["format"] == "curveskel-skeleton/1"
    r = run_cli(mesh_file, "-q", "--max-iterations", "-1")           # errors still said
    assert r.returncode == 2 and r.stderr.startswith("error: max_iterations must be >= 0")


# -- --version, --help, licence -----------------------------------------------------------------------
def test_version_comes_from_the_package_and_matches_the_manifest():
    from curveskel_addon import __version__

    assert __version__ == MANIFEST["version"]
    r = run_cli("--version")
    assert r.returncode == 0 and r.stdout == f"curveskel {__version__}\n"
    m = subprocess.run([sys.executable, "-m", "curveskel_addon.cli", "--version"], cwd=ROOT,
                       capture_output=True, text=True, timeout=60)
    assert m.returncode == 0 and m.stdout == f"curveskel {__version__}\n"


def test_help_says_what_the_seed_does_and_the_output_policy():
    h = " ".join(run_cli("--help").stdout.split())
    assert "--seed SEED where the pole search starts" in h
    assert "it can change which branches the first approximation finds and the joint count" in h
    assert "a symbolic link is followed and the file it points to is replaced" in h
    assert "a read-only file is refused" in h and "/dev/null" in h
    assert "--quiet" in h and "--version" in h


def test_the_licence_file_is_the_manifests():
    assert MANIFEST["license"] == ["SPDX:GPL-3.0-or-later"]
    text = (ROOT / "LICENSE").read_text()
    assert text.split("\n")[:2] == ["                    GNU GENERAL PUBLIC LICENSE",
                                    "                       Version 3, 29 June 2007"]
    # the full GPL v3 text (its "how to apply" notice is the -or-later one)
    words = " ".join(text.split())
    assert "either version 3 of the License, or (at your option) any later version" in words
    assert "END OF TERMS AND CONDITIONS" in words and len(text) > 30000


# -- the curveskel command -----------------------------------------------------------------------
def _curveskel(*args):
    return subprocess.run([sys.executable, "-m", "curveskel_addon.cli", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


def test_the_subcommand_gives_the_scripts_skeleton(mesh_file, tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    r1 = _curveskel("skeletonize", mesh_file, "--json", a)
    r2 = run_cli(mesh_file, "--json", b)
    assert r1.returncode == r2.returncode == 0, r1.stderr + r2.stderr
    da, db = json.loads(a.read_text()), json.loads(b.read_text())
    for d in (da, db):
        d["meta"].pop("timings", None)
        d.pop("timings", None)
    assert da["joints"] == db["joints"] and da["bones"] == db["bones"] and da["mapping"] == db["mapping"]


def test_an_unknown_subcommand_is_one_line_with_a_suggestion():
    r = _curveskel("skeletonise", "x.obj")
    assert r.returncode == 2
    assert r.stderr == ("error: unknown command 'skeletonise' (did you mean 'skeletonize'?); "
                        "commands: skeletonize (see curveskel --help)\n")
    h = _curveskel("--help")
    assert h.returncode == 0 and "skeletonize  curve-skeleton of one mesh file" in h.stdout


def test_a_subcommand_is_one_module_and_one_line():
    """The dispatch: COMMANDS names a module of curveskel_addon.cli with main(argv, prog)."""
    import importlib

    from curveskel_addon.cli import COMMANDS

    for name, (module, what) in COMMANDS.items():
        mod = importlib.import_module(f"curveskel_addon.cli.{module}")
        assert callable(mod.main) and what
    r = _curveskel("skeletonize", "--help")
    assert r.returncode == 0 and r.stdout.startswith("usage: curveskel skeletonize ")
