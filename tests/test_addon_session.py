"""The F12 render session with a stand-in engine and renderer (no Blender needed).

The real engine is exercised in test_addon_render.py; here every path through the session
is forced on purpose: normal completion, cancel by test_break, KeyboardInterrupt, export
errors, invalid scenes and renderer failures. In all of them the render result must be
begun and ended exactly once, and a partial image must survive a cancel.
"""

from __future__ import annotations

import math
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from addon.display import ResultBuffer
from addon.export.messages import ExportError
from addon.export.scene import ExportResult
from addon.export.validate import describe_scene_error
from addon.session import (
    COMPILING_TEXT,
    MAX_REPORTED_WARNINGS,
    PREVIEW_MAX_BOUNCES,
    PREVIEW_SAMPLES,
    RenderSession,
    format_duration,
    main_module_hidden,
    stats_text,
)
from renderer.scene import Film, Material, Mesh, Scene

WIDTH, HEIGHT = 4, 3


class FakeResult:
    def __init__(self) -> None:
        self.pixels = None
        rect = SimpleNamespace(foreach_set=self._store)
        self.layers = [SimpleNamespace(passes={"Combined": SimpleNamespace(rect=rect)})]

    def _store(self, values) -> None:
        self.pixels = np.array(values, dtype=np.float32).reshape(HEIGHT, WIDTH, 4)


class FakeEngine:
    """Records what the session asks of Blender's RenderEngine."""

    resolution_x, resolution_y = WIDTH, HEIGHT

    def __init__(self, break_after: int | None = None) -> None:
        self.calls: list[str] = []
        self.progress: list[float] = []
        self.stats: list[str] = []
        self.reports: list[tuple[str, str]] = []
        self.results: list[FakeResult] = []
        self.break_after = break_after

    def begin_result(self, x, y, w, h):
        assert (x, y, w, h) == (0, 0, WIDTH, HEIGHT)
        self.calls.append("begin")
        self.results.append(FakeResult())
        return self.results[-1]

    def update_result(self, result) -> None:
        self.calls.append("update")

    def end_result(self, result) -> None:
        self.calls.append("end")

    def update_progress(self, value: float) -> None:
        self.progress.append(value)

    def update_stats(self, stats: str, info: str) -> None:
        self.stats.append(info)

    def test_break(self) -> bool:
        return self.break_after is not None and len(self.progress) >= self.break_after

    def report(self, kind, text: str) -> None:
        self.reports.append((next(iter(kind)), text))


def settings(**overrides):
    values = dict(samples=3, time_limit=0.0, target_error=0.0, workers=1, cluster="")
    values.update(overrides)
    return SimpleNamespace(**values)


def depsgraph(**overrides):
    return SimpleNamespace(scene=SimpleNamespace(haze=settings(**overrides)))


def valid_scene() -> Scene:
    quad = Mesh("Floor", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0]], np.float32),
                np.array([[0, 1, 2]], np.int32), ["Grey"])
    return Scene(film=Film(WIDTH, HEIGHT), materials=[Material("Grey")], meshes=[quad])


def exporter(scene: Scene | None = None, warnings: list[str] | None = None):
    def export(graph, film):
        assert (film.width, film.height) == (WIDTH, HEIGHT)
        return ExportResult(scene or valid_scene(), warnings or [])
    return export


def pass_image(spp: int) -> np.ndarray:
    """A recognisable image per pass: value = spp, plus the row index (row 0 = top)."""
    rows = np.arange(HEIGHT, dtype=np.float32)[:, None, None]
    return np.broadcast_to(spp + rows, (HEIGHT, WIDTH, 3)).astype(np.float32)


class FakeRenderer:
    """render_progressive stand-in: `passes` passes of one sample; may fail at one of them."""

    def __init__(self, passes: int = 3, fail_at: int | None = None, error: BaseException | None = None,
                 cold: bool = False):
        self.passes, self.fail_at, self.error = passes, fail_at, error
        self.cold = cold  # kernels missing from the cache: announce the compile, as the renderer does
        self.closed = False
        self.kwargs = None

    def __call__(self, scene, **kwargs):
        self.kwargs = kwargs
        return self._frames()

    def _frames(self):
        if self.cold:
            self.kwargs["on_compile"](["shade_surface", "shade_media"])
        try:
            for spp in range(1, self.passes + 1):
                if spp == self.fail_at:
                    raise self.error
                yield SimpleNamespace(image=pass_image(spp), spp=spp, spp_target=self.passes,
                                      elapsed=0.5 * spp, error_estimate=math.nan if spp < 2 else 0.1 / spp)
        finally:
            self.closed = True


def run(engine: FakeEngine, renderer: FakeRenderer, export=None, **overrides) -> FakeEngine:
    RenderSession(engine, depsgraph(**overrides), renderer=renderer, exporter=export or exporter()).run()
    return engine


def shown_image(engine: FakeEngine) -> np.ndarray:
    """The final RGBA buffer turned back to Haze's row order (row 0 = top)."""
    return engine.results[0].pixels[::-1]


def test_complete_render_reports_progress_and_ends_the_result_once():
    engine = run(FakeEngine(), renderer := FakeRenderer(passes=3))
    assert engine.calls[0] == "begin" and engine.calls[-1] == "end" and engine.calls.count("end") == 1
    assert engine.progress == pytest.approx([1 / 3, 2 / 3, 1.0])
    assert "Sample 3/3" in engine.stats[-1] and "Elapsed 00:01.50" in engine.stats[-1]
    image = shown_image(engine)
    assert np.allclose(image[..., :3], pass_image(3)) and np.all(image[..., 3] == 1)
    assert renderer.closed
    assert set(renderer.kwargs) == {"workers", "target_error", "validate", "on_compile", "in_process",
                                    "cluster"}
    assert renderer.kwargs["cluster"] == ""  # this machine's workers unless a cluster is set
    assert renderer.kwargs["in_process"] is False  # the pool: Esc can stop any scene
    assert renderer.kwargs["workers"] == 1 and renderer.kwargs["target_error"] == 0.0
    assert not [r for r in engine.reports if r[0] == "ERROR"]
    assert COMPILING_TEXT not in engine.stats  # warm cache: nothing to say


def test_a_cluster_set_in_the_settings_renders_there():
    run(FakeEngine(), renderer := FakeRenderer(passes=1), cluster=" tcp://farm:8786 ")
    assert renderer.kwargs["cluster"] == "tcp://farm:8786"


def test_cold_cache_shows_the_compile_message_before_the_first_pass():
    engine = run(FakeEngine(), FakeRenderer(passes=2, cold=True))
    assert engine.stats[:3] == ["Haze | Exporting scene", "Haze | Rendering", COMPILING_TEXT]
    assert COMPILING_TEXT == "Haze | Compiling kernels (first run only)…"
    assert "Sample 2/2" in engine.stats[-1]


def test_test_break_keeps_the_partial_image():
    engine = run(FakeEngine(break_after=1), renderer := FakeRenderer(passes=5))
    assert renderer.closed
    assert np.allclose(shown_image(engine)[..., :3], pass_image(1))
    assert ("WARNING", "Haze: render stopped after 1 samples per pixel") in engine.reports
    assert engine.calls.count("begin") == 1 and engine.calls[-1] == "end"


def test_keyboard_interrupt_keeps_the_partial_image():
    engine = run(FakeEngine(), FakeRenderer(passes=5, fail_at=3, error=KeyboardInterrupt()))
    assert np.allclose(shown_image(engine)[..., :3], pass_image(2))
    assert ("WARNING", "Haze: render stopped after 2 samples per pixel") in engine.reports
    assert engine.calls[-1] == "end"


def test_export_error_is_reported_and_the_result_still_ended():
    def failing(graph, film):
        raise ExportError("Object 'Cube'", "is broken")

    engine = run(FakeEngine(), renderer := FakeRenderer(), export=failing)
    assert engine.reports == [("ERROR", "Object 'Cube': is broken")]
    assert engine.calls == ["begin", "end"] and renderer.kwargs is None
    assert np.all(shown_image(engine)[..., :3] == 0)


def test_invalid_scene_error_names_the_blender_object():
    scene = valid_scene()
    scene.meshes[0].indices = np.array([[0, 1, 7]], np.int32)
    engine = run(FakeEngine(), FakeRenderer(), export=exporter(scene))
    (kind, text), = engine.reports
    assert kind == "ERROR"
    assert text.startswith("Haze scene: 'Floor' (meshes[0].indices): index 7 out of range")


def test_a_render_too_large_for_memory_is_refused_before_it_starts(monkeypatch):
    import renderer.memory

    monkeypatch.setattr(renderer.memory, "available_memory_bytes", lambda: 1000)  # 1 kB left
    engine = run(FakeEngine(), renderer := FakeRenderer())
    (kind, text), = engine.reports
    assert kind == "ERROR" and "needs about" in text and "memory" in text, text
    assert renderer.kwargs is None and engine.calls == ["begin", "end"]


def test_a_large_image_is_counted_by_the_memory_check(monkeypatch):
    """Not only the film: a scene's images count, and the refusal names the largest item."""
    import renderer.memory
    from renderer.shading.program import ImageTexture

    scene = valid_scene()  # zeros: pages the test never touches cost no memory
    scene.images = [ImageTexture("Huge", np.zeros((4096, 4096, 4), np.float32))]  # 268 MB of texels
    monkeypatch.setattr(renderer.memory, "available_memory_bytes", lambda: 600_000_000)
    engine = run(FakeEngine(), renderer := FakeRenderer(), export=exporter(scene))
    (kind, text), = engine.reports
    assert kind == "ERROR" and "Huge" in text, text
    assert renderer.kwargs is None


def test_workers_are_capped_at_what_memory_allows_and_it_is_said(monkeypatch):
    import renderer.memory

    per_worker = renderer.memory.PROCESS_BYTES
    monkeypatch.setattr(renderer.memory, "usable_cores", lambda: 8)
    monkeypatch.setattr(renderer.memory, "available_memory_bytes", lambda: int(2.5 * per_worker))
    engine = run(FakeEngine(), renderer := FakeRenderer(), workers=4)
    assert renderer.kwargs["workers"] == 2
    assert any(kind == "WARNING" and "2 worker processes, not 4" in text for kind, text in engine.reports)


def test_renderer_failure_is_reported_not_raised():
    engine = run(FakeEngine(), renderer := FakeRenderer(fail_at=2, error=ValueError("kernel exploded")))
    assert ("ERROR", "Haze: ValueError: kernel exploded") in engine.reports
    assert renderer.closed and engine.calls[-1] == "end"
    assert np.allclose(shown_image(engine)[..., :3], pass_image(1))


def test_many_warnings_are_capped_in_the_ui(capsys):
    warnings = [f"Object 'O{i}': something" for i in range(MAX_REPORTED_WARNINGS + 5)]
    engine = run(FakeEngine(), FakeRenderer(passes=1), export=exporter(warnings=warnings))
    shown = [text for kind, text in engine.reports if kind == "WARNING"]
    assert shown[:MAX_REPORTED_WARNINGS] == warnings[:MAX_REPORTED_WARNINGS]
    assert shown[-1] == "Haze: 5 more warnings were printed to the console"
    assert "Object 'O24': something" in capsys.readouterr().out


class RecordingRenderer(FakeRenderer):
    """Keeps the scene it was asked to render."""

    def __call__(self, scene, **kwargs):
        self.scene = scene
        return super().__call__(scene, **kwargs)


def test_material_preview_is_capped_and_quiet():
    """A preview (engine.is_preview) renders at most PREVIEW_SAMPLES samples with at most
    PREVIEW_MAX_BOUNCES bounces, Combined only, and reports no export warnings; a normal
    render keeps the scene's settings."""
    scene = valid_scene()
    scene.integrator.spp, scene.integrator.max_bounces, scene.integrator.time_limit = 512, 12, 0.0
    engine = FakeEngine()
    engine.is_preview = True
    renderer = RecordingRenderer(passes=1)
    run(engine, renderer, export=exporter(scene, warnings=["Material 'M': a texture is ignored"]))
    integrator = renderer.scene.integrator
    assert (integrator.spp, integrator.max_bounces) == (PREVIEW_SAMPLES, PREVIEW_MAX_BOUNCES)
    assert engine.reports == [] and engine.calls[0] == "begin" and engine.calls[-1] == "end"
    scene = valid_scene()
    scene.integrator.spp, scene.integrator.max_bounces = 512, 12
    renderer = RecordingRenderer(passes=1)
    warnings = ["Material 'M': a texture is ignored"]
    engine = run(FakeEngine(), renderer, export=exporter(scene, warnings=warnings))
    assert (renderer.scene.integrator.spp, renderer.scene.integrator.max_bounces) == (512, 12)
    assert [text for _, text in engine.reports] == ["Material 'M': a texture is ignored"]


def test_result_buffer_flips_rows_for_blender():
    buffer = ResultBuffer(WIDTH, HEIGHT)
    buffer.fill(pass_image(0))
    flat = buffer.flat()
    assert flat.dtype == np.float32 and flat.shape == (WIDTH * HEIGHT * 4,)
    assert flat[0] == HEIGHT - 1  # Blender's first pixel is the bottom-left one: Haze's last row
    with pytest.raises(ValueError, match="returned a 5x3 image for a 4x3 render"):
        buffer.fill(np.zeros((3, 5, 3), np.float32))


def test_main_module_is_hidden_only_while_workers_start():
    main = sys.modules["__main__"]
    before = (getattr(main, "__file__", None), main.__spec__)
    with main_module_hidden():
        assert getattr(main, "__file__", None) is None and main.__spec__ is None
    assert (getattr(main, "__file__", None), main.__spec__) == before


def test_stats_text_and_durations():
    progress = SimpleNamespace(spp=16, spp_target=64, elapsed=65.5, error_estimate=0.0123)
    assert stats_text(progress, 0.0) == "Sample 16/64 | Elapsed 01:05.50 | Remaining 03:16.50 | Noise 0.0123"
    assert "Remaining 00:04.50" in stats_text(progress, 70.0)  # the time limit comes first
    assert format_duration(math.inf) == "--:--"


def test_describe_scene_error_falls_back_to_the_path():
    from renderer.errors import SceneError

    result = ExportResult(valid_scene(), [], ["Key Light"])
    assert describe_scene_error(SceneError("lights[0].intensity", "must be >= 0"), result) == \
        "'Key Light' (lights[0].intensity): must be >= 0"
    assert describe_scene_error(SceneError("camera.fov", "bad"), result) == "camera.fov: bad"
