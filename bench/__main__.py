"""`python -m bench [speed] [options]`: the speed benchmark (default).

Other studies register here as subcommands (see COMMANDS)."""

import importlib
import sys

COMMANDS = {"speed": "bench.speed", "convergence": "bench.convergence", "contrast": "bench.contrast",
            "cloud512": "bench.cloud512"}


def main(argv: list[str]) -> int:
    name = argv[0] if argv and argv[0] in COMMANDS else "speed"
    rest = argv[1:] if argv and argv[0] in COMMANDS else argv
    return importlib.import_module(COMMANDS[name]).main(rest)


raise SystemExit(main(sys.argv[1:]))
