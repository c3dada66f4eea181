"""The command line for pipeline TDs: `--version`, documented exit statuses, and progress
that suits where stderr goes (a bar on a terminal, plain lines in a log, or nothing)."""

from __future__ import annotations

import io
import subprocess
import sys
import tomllib
from pathlib import Path

import renderer
from examples.scenes import cornell_box
from renderer import cli, cli_output
from renderer.scenefile import save_scene

REPO = Path(__file__).resolve().parents[1]


def test_version_is_the_packages_and_matches_its_metadata():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    manifest = tomllib.loads((REPO / "blender_manifest.toml").read_text())
    assert renderer.__version__ == project["version"] == manifest["version"]
    run = subprocess.run([sys.executable, "-m", "renderer", "--version"], capture_output=True, text=True,
                         timeout=60, cwd=REPO)
    assert run.returncode == 0
    assert run.stdout.strip() == f"python -m renderer {cli.haze_version()}"


def test_help_documents_every_exit_status():
    run = subprocess.run([sys.executable, "-m", "renderer", "render", "--help"], capture_output=True,
                         text=True, timeout=60, cwd=REPO)
    text = " ".join(run.stdout.split())
    for status in ("0 the image is written", "1 the render failed", "2 the command or the scene was refused",
                   "130 Ctrl-C", "128+N stopped by signal N"):
        assert status in text


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_auto_progress_is_a_bar_on_a_terminal_and_plain_lines_elsewhere():
    assert cli_output.progress_mode("auto", Terminal()) == "bar"
    assert cli_output.progress_mode("auto", io.StringIO()) == "plain"
    assert cli_output.progress_mode("none", Terminal()) == "none"


def test_plain_progress_is_one_line_per_interval_and_the_last(monkeypatch):
    said: list[tuple[str, str]] = []
    monkeypatch.setattr(cli_output, "say", lambda text, end="\n": said.append((text, end)))
    printer = cli_output.ProgressPrinter("plain", total=64)
    for k, elapsed in enumerate((0.5, 3.0, 9.0, 10.6, 12.0, 20.0, 21.0)):
        printer.show(k + 1, elapsed, float("nan"))
    printer.finish()
    lines = [text for text, end in said]
    assert all(end == "\n" and "\r" not in text for text, end in said)
    # One at the start, then at 10.6 s and 21.0 s (10 s apart), and the last state at the end.
    assert [line.split("]")[1].split()[0] for line in lines] == ["1/64", "4/64", "7/64"]
    said.clear()
    quiet = cli_output.ProgressPrinter("none", total=64)
    quiet.show(1, 50.0, 0.1)
    quiet.finish()
    assert said == []


def test_a_logged_render_has_no_carriage_returns(tmp_path):
    save_scene(cornell_box(size=8, spp=2), tmp_path / "scene")
    out = tmp_path / "out.exr"
    command = [sys.executable, "-m", "renderer", "render", str(tmp_path / "scene"), "-o", str(out),
               "--spp", "2", "--workers", "1"]
    run = subprocess.run(command, capture_output=True, text=True, timeout=600, cwd=REPO)
    assert run.returncode == 0, run.stderr
    assert "\r" not in run.stderr  # stderr is a pipe here: plain lines
    assert "2/2 spp" in run.stderr and "M samples/s" in run.stderr
