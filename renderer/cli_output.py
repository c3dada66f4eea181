"""What the command line writes on stderr while it renders: progress as a bar redrawn in
place on a terminal, plain lines in a log (farm jobs, CI), or nothing, and the compile
ticker. Every write goes through say(), which a broken stream never turns into a lost render."""

from __future__ import annotations

import sys
import threading
import time

PROGRESS_MODES = ("auto", "bar", "plain", "none")
PLAIN_INTERVAL = 10.0  # seconds between plain progress lines (logs of farm jobs, CI)


def say(text: str, end: str = "\n") -> None:
    """Write to stderr; a closed pipe or a full disk there drops the text, never the render
    (the image is what matters, and the exit status says how it went)."""
    try:
        print(text, end=end, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # EPIPE, ENOSPC, EIO; ValueError: stderr closed
        pass


def progress_mode(requested: str, stream=None) -> str:
    """The bar only where a terminal shows it; carriage returns garble a log file."""
    if requested != "auto":
        return requested
    stream = sys.stderr if stream is None else stream
    try:
        return "bar" if stream.isatty() else "plain"
    except (AttributeError, ValueError):  # a replaced or closed stream
        return "plain"


class ProgressPrinter:
    """Progress lines on stderr in one of PROGRESS_MODES (resolved: bar, plain or none)."""

    def __init__(self, mode: str, total: int) -> None:
        self.mode, self.total = mode, total
        self.last_line = -float("inf")
        self.pending = ""

    def show(self, done: int, elapsed: float, err: float) -> None:
        text = bar(done, self.total, elapsed, err)
        if self.mode == "bar":
            say(text, end="")
        elif self.mode == "plain":
            self.pending = text.lstrip("\r")
            if elapsed - self.last_line >= PLAIN_INTERVAL:
                self.last_line = elapsed
                say(self.pending)
                self.pending = ""

    def finish(self) -> None:
        if self.mode == "bar":
            say("")
        elif self.mode == "plain" and self.pending:
            say(self.pending)  # the last state, once

def bar(done: int, total: int, elapsed: float, err: float) -> str:
    frac = min(1.0, done / max(total, 1))
    width = 30
    filled = int(frac * width)
    eta = elapsed / frac - elapsed if frac > 0 else float("nan")
    err_s = f"  relMSE~{err:.2e}" if err == err else ""
    return (f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} spp  {elapsed:6.1f}s elapsed"
            f"  ETA {eta:5.1f}s{err_s}")


class CompileTicker:
    """'compiling kernels (first run only): N s' on stderr, once a second in place, until
    stopped; plain: one line when it starts and one when it is done (for logs); quiet: none."""

    def __init__(self, interval: float = 1.0, plain: bool = False, quiet: bool = False):
        self.interval = interval
        self.plain, self.quiet = plain, quiet
        self._done = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self, names: list[str]) -> None:
        t0 = time.perf_counter()
        if self.quiet:
            return
        if self.plain:
            say("compiling kernels (first run only)")

        def tick() -> None:
            while True:
                if not self.plain:
                    say(f"\rcompiling kernels (first run only): {time.perf_counter() - t0:.0f} s", end="")
                if self._done.wait(self.interval):
                    break
            say(f"{'' if self.plain else chr(13)}compiled kernels in {time.perf_counter() - t0:.1f} s")

        self._thread = threading.Thread(target=tick, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        if self._thread is not None:
            self._done.set()
            self._thread.join()
            self._thread = None
