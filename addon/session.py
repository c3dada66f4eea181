"""One render: export, progressive rendering, display and cleanup (no bpy import here).

The render result is always begun and ended, even when the export or the renderer fails:
Blender expects a result from every render, and a headless
`bpy.ops.render.render(write_still=True)` crashes without one. Stopping (Esc in the UI,
test_break, or Ctrl-C / KeyboardInterrupt in a background script) keeps the samples done.

The engine object is only used through RenderEngine's methods (begin_result, update_result,
end_result, update_progress, update_stats, test_break, report) and resolution_x/_y, so the
session can be exercised with a stand-in engine.
"""

from __future__ import annotations

import math
import sys
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from .display import ResultBuffer, render_region, write_pass, write_result
from .export.messages import ExportError
from .export.validate import export_validated
from .passes import (
    COMBINED,
    DENOISING_ALBEDO,
    DENOISING_NORMAL,
    NOISY_IMAGE,
    denoising_enabled,
    needs_aovs,
    needs_light_aovs,
    requested_passes,
)

PUSH_INTERVAL = 1.0  # seconds between image updates shown to the user
MAX_DISPLAY_SHARE = 0.02  # pushes may take at most this share of the render time
MAX_REPORTED_WARNINGS = 20  # more go to the console only, so the UI is not flooded
COMPILING_TEXT = "Haze | Compiling kernels (first run only)…"
# Material previews (the Material tab's sphere, the material icons): small and redrawn on
# every edit, so a few samples and bounces, Combined only, no warnings. No time limit: one
# would leave the first previews black while the kernels compile.
PREVIEW_SAMPLES = 16
PREVIEW_MAX_BOUNCES = 4
# Previews of scenes with media (a volume material) take half the samples: their samples
# cost 3-4x a surface's, and 16 of them made a volume preview take 5.3 s warm against a
# surface's 1.7-2.6 s (128x128 plus its icon, at load 12: python -m bench preview_time).
PREVIEW_VOLUME_SAMPLES = 8

_active_renders = 0  # RenderSessions running in this process (the cache must not be cleared then)


def rendering() -> bool:
    """True while a render of this process runs (Clear kernel cache refuses then)."""
    return _active_renders > 0


@contextmanager
def counted_render():
    global _active_renders
    _active_renders += 1
    try:
        yield
    finally:
        _active_renders -= 1


def format_duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "--:--"
    minutes, rest = divmod(max(seconds, 0.0), 60.0)
    return f"{int(minutes):02d}:{rest:05.2f}"


def remaining_time(progress, time_limit: float) -> float:
    """Estimated seconds left: by the sample rate so far, capped by the time limit."""
    if progress.spp <= 0:
        return math.inf
    by_samples = progress.elapsed * (progress.spp_target - progress.spp) / progress.spp
    if time_limit > 0.0:
        return min(by_samples, time_limit - progress.elapsed)
    return by_samples


def progress_fraction(progress, time_limit: float) -> float:
    fraction = progress.spp / max(progress.spp_target, 1)
    if time_limit > 0.0:
        fraction = max(fraction, progress.elapsed / time_limit)
    return min(max(fraction, 0.0), 1.0)


def stats_text(progress, time_limit: float) -> str:
    error = progress.error_estimate
    noise = f"{error:.3g}" if error is not None and math.isfinite(error) else "--"
    return (
        f"Sample {progress.spp}/{progress.spp_target} | Elapsed {format_duration(progress.elapsed)} | "
        f"Remaining {format_duration(remaining_time(progress, time_limit))} | Noise {noise}"
    )


@contextmanager
def main_module_hidden():
    """Hide the __main__ script from multiprocessing while worker processes start.

    The renderer's workers are spawned processes, and spawn re-runs the parent's __main__
    file in each child. Under Blender that file is a user script (`blender -P script.py`,
    or a bpy-module script) that imports bpy, which cannot work in a plain worker process,
    so the worker dies. The workers need nothing from __main__.
    """
    main = sys.modules.get("__main__")
    saved = {name: vars(main)[name] for name in ("__file__", "__spec__") if main and name in vars(main)}
    try:
        if main is not None:
            main.__spec__ = None
            if "__file__" in saved:
                del main.__file__
        yield
    finally:
        for name, value in saved.items():
            setattr(main, name, value)


def passes_without_main(frames: Iterator) -> Iterator:
    """Iterate render passes; workers may be started at any pass, so hide __main__ each time."""
    while True:
        with main_module_hidden():
            try:
                progress = next(frames)
            except StopIteration:
                return
        yield progress


def preview_settings(integrator, has_media: bool = False) -> None:
    """A material preview's settings: at most PREVIEW_SAMPLES samples (PREVIEW_VOLUME_SAMPLES
    with media) and PREVIEW_MAX_BOUNCES bounces, whatever the scene asks for."""
    cap = PREVIEW_VOLUME_SAMPLES if has_media else PREVIEW_SAMPLES
    integrator.spp = min(int(integrator.spp), cap)
    integrator.max_bounces = min(int(integrator.max_bounces), PREVIEW_MAX_BOUNCES)


class RenderSession:
    """One F12 render: export, progressive rendering, display, and cleanup."""

    def __init__(self, engine, depsgraph, renderer: Callable | None = None,
                 exporter: Callable | None = None) -> None:
        self.engine = engine
        self._renderer = renderer  # render_progressive stand-in (tests); None = the real one
        self._exporter = exporter  # export function stand-in (tests); None = the real one
        self.depsgraph = depsgraph
        self.settings = depsgraph.scene.haze
        self.width, self.height = int(engine.resolution_x), int(engine.resolution_y)
        render = getattr(depsgraph.scene, "render", None)
        # Blender's result holds the Render Region only; the renderer renders just that window.
        region = render_region(render, self.width, self.height)
        self.window = region or (0, 0, self.width, self.height)
        self.transparent = bool(getattr(render, "film_transparent", False))
        self.buffer = ResultBuffer(self.window[2], self.window[3])
        # The passes Blender's result holds for this view layer (update_render_passes), and
        # whether the final image is denoised.
        self.preview = bool(getattr(engine, "is_preview", False))
        view_layer = getattr(depsgraph, "view_layer", None)
        self.passes = [COMBINED] if self.preview else requested_passes(depsgraph.scene, view_layer)
        self.denoise = denoising_enabled(depsgraph.scene) and not self.preview
        self.camera = None  # the exported camera (Depth and Denoising Normal are relative to it)
        self.latest = None  # last Progress received
        self.cancelled = False

    def run(self) -> None:
        with counted_render():
            self._run()

    def _run(self) -> None:
        result = self.engine.begin_result(0, 0, self.window[2], self.window[3])
        try:
            self._render(result)
        except KeyboardInterrupt:
            self.cancelled = True
        except ExportError as error:
            self.engine.report({"ERROR"}, str(error))
        except Exception as error:  # the renderer's own failures must not take Blender down
            traceback.print_exc()
            self.engine.report({"ERROR"}, f"Haze: {type(error).__name__}: {error}")
        finally:
            self._finish(result)

    def _finish(self, result) -> None:
        if result is None:
            return
        if self.latest is not None:
            self._fill()
            self._final_passes(result)
        write_result(result, self.buffer)
        self.engine.end_result(result)
        if self.cancelled:
            samples = self.latest.spp if self.latest is not None else 0
            self.engine.report({"WARNING"}, f"Haze: render stopped after {samples} samples per pixel")

    def _render(self, result) -> None:
        if self._renderer is None and not self._cluster():
            from renderer.workers import start_workers  # the standard library only: quick

            start_workers(1)  # its start-up overlaps the export and this process's imports
        exported = export_validated(self.depsgraph, (self.width, self.height), exporter=self._exporter,
                                    on_start=lambda: self.engine.update_stats("", "Haze | Exporting scene"),
                                    on_warnings=self._report_warnings)
        if self.preview:
            preview_settings(exported.scene.integrator, bool(exported.scene.media))
        # The passes cost nothing unless asked for: only then does the renderer write them.
        exported.scene.film.aovs = needs_aovs(self.passes, self.denoise)
        exported.scene.film.light_aovs = needs_light_aovs(self.passes)
        self.camera = exported.scene.camera
        workers = self._check_memory(exported.scene)
        render_progressive = self._renderer
        if render_progressive is None:
            from renderer.render import render_progressive

        self.engine.update_stats("", "Haze | Rendering")
        # Always the worker pool, one worker included: Esc and the time limit can only stop a
        # numba kernel in another process (the pool's workers persist across renders).
        frames = render_progressive(exported.scene, workers=workers,
                                    target_error=float(self.settings.target_error), validate=False,
                                    on_compile=self._on_compile, in_process=False,
                                    cluster=self._cluster())
        try:
            self._consume(frames, result)
        finally:
            frames.close()  # stops the work in flight, also on cancel or error
        note = getattr(self.latest, "note", "")
        if note:
            self.engine.report({"WARNING"}, f"Haze: {note}")

    def _cluster(self) -> str:
        """The Dask scheduler's address, "local", or "" for this machine's worker pool."""
        return str(getattr(self.settings, "cluster", "")).strip()

    def _check_memory(self, scene) -> int:
        """The worker processes to render with: the Workers setting, capped at the cores and
        memory this machine has for the scene (said once when fewer); a render that does not
        fit even so is refused before it starts, naming its largest item (the film, a grid,
        an image, the environment map...), not a crash halfway."""
        from renderer.errors import SceneError
        from renderer.memory import check_scene_memory, workers_allowed

        asked = self._workers()
        if self._cluster():  # the cluster's workers are on other machines: this one holds the scene
            workers = asked
        else:
            workers = workers_allowed(scene, asked)
            if workers < asked and not self.preview:
                self.engine.report({"WARNING"}, f"Haze: rendering with {workers} worker processes, not "
                                   f"{asked}: as many as this machine's cores and memory allow")
        try:
            check_scene_memory(scene, 1 if self._cluster() else workers)
        except SceneError as error:
            raise ExportError("Haze", str(error)) from error
        return workers

    def _on_compile(self, names: list[str]) -> None:
        """The kernels are not in the cache: say why the first image takes minutes."""
        self.engine.update_stats("", COMPILING_TEXT)
        print(f"Haze: compiling kernels (first run only): {', '.join(names)}", file=sys.stderr, flush=True)

    def _workers(self) -> int:
        from .export.scene import worker_count

        return worker_count(self.settings, getattr(self.depsgraph.scene, "render", None))

    def _report_warnings(self, warnings: list[str]) -> None:
        if self.preview:
            return  # a preview redraws on every edit: the render itself reports them
        for text in warnings[:MAX_REPORTED_WARNINGS]:
            self.engine.report({"WARNING"}, text)
        if len(warnings) > MAX_REPORTED_WARNINGS:
            for text in warnings[MAX_REPORTED_WARNINGS:]:
                print(f"Haze warning: {text}")
            self.engine.report({"WARNING"}, f"Haze: {len(warnings) - MAX_REPORTED_WARNINGS} more warnings "
                               "were printed to the console")

    def _consume(self, frames, result) -> None:
        last_push = time.monotonic()
        interval = PUSH_INTERVAL
        time_limit = float(self.settings.time_limit)
        for progress in passes_without_main(frames):
            self.latest = progress
            self.engine.update_progress(progress_fraction(progress, time_limit))
            self.engine.update_stats("", "Haze | " + stats_text(progress, time_limit))
            if time.monotonic() - last_push >= interval:
                started = time.monotonic()
                self._push(result)
                last_push = time.monotonic()
                # Huge images push less often, so showing them never costs over 2 % of the time.
                interval = max(PUSH_INTERVAL, (last_push - started) / MAX_DISPLAY_SHARE)
            if self.engine.test_break():
                self.cancelled = True
                return

    def _fill(self) -> None:
        # Alpha comes from the Progress's film (its alpha sums); without one, alpha stays 1.
        film = getattr(self.latest, "film", None)
        alpha = film.alpha_image() if self.transparent and film is not None else None
        self.buffer.fill(self.latest.image, alpha)

    def _final_passes(self, result) -> None:
        """Write the requested passes, and denoise Combined (keeping the raw image as Noisy
        Image), from the last film. A failed denoise keeps the raw image and says why."""
        film = getattr(self.latest, "film", None)
        if film is None or film.aov is None or self.camera is None:
            return
        from renderer.passes import film_passes

        names = tuple(p.name for p in self.passes if p not in (COMBINED, NOISY_IMAGE))
        wanted = set(names) | ({DENOISING_ALBEDO.name, DENOISING_NORMAL.name} if self.denoise else set())
        images = film_passes(film, self.camera, tuple(sorted(wanted)))
        for name in names:
            write_pass(result, name, images[name])
        if self.denoise:
            self._denoise(result, images)

    def _denoise(self, result, images: dict) -> None:
        from renderer.denoise import DenoiseError, denoise

        noisy = self.latest.image
        alpha = self.buffer.rgba[::-1, :, 3]  # the buffer is bottom-up; passes take top-down images
        write_pass(result, NOISY_IMAGE.name, noisy, alpha)
        self.engine.update_stats("", "Haze | Denoising")
        try:
            clean = denoise(noisy, images[DENOISING_ALBEDO.name], images[DENOISING_NORMAL.name])
        except DenoiseError as error:
            self.engine.report({"WARNING"}, f"Haze: not denoised: {error}")
            return
        self.buffer.fill(clean)

    def _push(self, result) -> None:
        self._fill()
        write_result(result, self.buffer)
        self.engine.update_result(result)
