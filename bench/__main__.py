"""`python -m bench [NAME] [options]`: one command per benchmark, measurement or developer
tool; NAME defaults to speed. `python -m bench --help` lists them, `python -m bench NAME
--help` tells one's options. Run from the repository root."""

import ast
import importlib
import sys
from pathlib import Path

COMMANDS = {
    # benchmarks
    "speed": "bench.speed", "convergence": "bench.convergence", "contrast": "bench.contrast",
    "cloud512": "bench.cloud512", "cluster": "bench.cluster", "first_image": "bench.first_image",
    "scaling": "bench.scaling",
    # measurements
    "denoise_convergence": "bench.denoise_convergence", "noise_per_sample": "bench.noise_per_sample",
    "pass_cost": "bench.pass_cost", "sparse_grid_cost": "bench.sparse_grid_cost",
    "worker_memory": "bench.worker_memory", "speed_ab": "bench.speed_ab",
    "kernel_profile": "bench.kernel_profile", "hdri_variance": "bench.hdri_variance",
    "preview_time": "bench.preview_time", "program_cost": "bench.program_cost",
    "procedural_tracking": "bench.procedural_tracking",
    "procedural_volume_cycles": "bench.procedural_volume_cycles",
    # developer tools
    "golden": "bench.golden", "import_cycles": "bench.import_cycles", "scene_fuzz": "bench.scene_fuzz",
    "cycles_reference": "bench.cycles_reference", "blend_scene": "bench.blend_scene",
}


def summary(module: str) -> str:
    """The first line of a command's docstring, read without importing it (imports are slow)."""
    path = Path(__file__).resolve().parent / f"{module.rpartition('.')[2]}.py"
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    return doc.strip().splitlines()[0] if doc.strip() else ""


def usage() -> str:
    width = max(map(len, COMMANDS))
    lines = [__doc__, "", "commands:"]
    lines += [f"  {name:{width}s}  {summary(module)}" for name, module in COMMANDS.items()]
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if argv and argv[0] in ("-h", "--help", "help"):
        print(usage())
        return 0
    name = argv[0] if argv and argv[0] in COMMANDS else "speed"
    rest = argv[1:] if argv and argv[0] in COMMANDS else argv
    return importlib.import_module(COMMANDS[name]).main(rest)


raise SystemExit(main(sys.argv[1:]))
