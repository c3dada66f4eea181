"""The convergence benchmark's plot: relMSE against wall time on log-log axes, one SVG per
scene, written as plain SVG text (no plotting library)."""

from __future__ import annotations

import math
from pathlib import Path

from .metrics import TARGETS
from .reports import SceneResult

PALETTE = ("#1f77b4", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf")
CYCLES_COLOR = "#d62728"


def svg_plot(result: SceneResult, path: Path, size: int, workers: int) -> None:
    """relMSE against seconds on log-log axes, one line per curve; 1e-2 and 1e-3 marked."""
    series = [(c, PALETTE[i % len(PALETTE)], "") for i, c in enumerate(result.haze)]
    if result.cycles is not None:
        series.append((result.cycles, CYCLES_COLOR, "6,3"))
    if result.cycles_vs_haze is not None:
        series.append((result.cycles_vs_haze, CYCLES_COLOR, "2,3"))
    points = [(t, e) for c, _, _ in series for t, e in zip(c.seconds, c.relmse) if t > 0 and e > 0]
    xs, ys = [p[0] for p in points], [p[1] for p in points] + list(TARGETS)
    axes = LogAxes(min(xs), max(xs), min(ys), max(ys))
    parts = [axes.frame(f"{result.scene.name}: relMSE against wall time ({size}x{size}, {workers} cores)")]
    for target in TARGETS:
        parts.append(axes.hline(target))
    for curve, color, dash in series:
        parts.append(axes.polyline(curve.seconds, curve.relmse, color, dash))
    parts.append(legend([(c.label, color, dash) for c, color, dash in series], axes))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" width="{LogAxes.WIDTH}" '
                    f'height="{LogAxes.HEIGHT}" font-family="sans-serif" font-size="12">\n'
                    '<rect width="100%" height="100%" fill="white"/>\n' + "\n".join(parts) + "\n</svg>\n")


class LogAxes:
    """Maps data to SVG pixels on decade-aligned log-log axes."""

    WIDTH, HEIGHT = 720, 460
    LEFT, RIGHT, TOP, BOTTOM = 70, 200, 40, 50

    def __init__(self, x0: float, x1: float, y0: float, y1: float):
        self.x0, self.x1 = math.floor(math.log10(x0)), math.ceil(math.log10(x1))
        self.y0, self.y1 = math.floor(math.log10(y0)), math.ceil(math.log10(y1))
        self.x1 = max(self.x1, self.x0 + 1)
        self.y1 = max(self.y1, self.y0 + 1)

    def px(self, x: float) -> float:
        span = self.WIDTH - self.LEFT - self.RIGHT
        return self.LEFT + (math.log10(x) - self.x0) / (self.x1 - self.x0) * span

    def py(self, y: float) -> float:
        span = self.HEIGHT - self.TOP - self.BOTTOM
        return self.HEIGHT - self.BOTTOM - (math.log10(y) - self.y0) / (self.y1 - self.y0) * span

    def frame(self, title: str) -> str:
        left, right = self.LEFT, self.WIDTH - self.RIGHT
        top, bottom = self.TOP, self.HEIGHT - self.BOTTOM
        out = [f'<text x="{left}" y="22" font-size="14">{title}</text>',
               f'<rect x="{left}" y="{top}" width="{right - left}" height="{bottom - top}" fill="none" '
               'stroke="black"/>']
        for k in range(self.x0, self.x1 + 1):
            for m in range(1, 10) if k < self.x1 else (1,):
                x = self.px(m * 10.0**k)
                tick = 6 if m == 1 else 3
                out.append(f'<line x1="{x:.1f}" y1="{bottom}" x2="{x:.1f}" y2="{bottom - tick}" '
                           'stroke="black"/>')
                if m == 1:
                    out.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{bottom}" stroke="#ddd"/>')
                    out.append(f'<text x="{x:.1f}" y="{bottom + 16}" text-anchor="middle">{10.0**k:g}</text>')
        for k in range(self.y0, self.y1 + 1):
            y = self.py(10.0**k)
            out.append(f'<line x1="{left}" y1="{y:.1f}" x2="{right}" y2="{y:.1f}" stroke="#ddd"/>')
            out.append(f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end">1e{k}</text>')
        out.append(f'<text x="{(left + right) / 2}" y="{self.HEIGHT - 12}" text-anchor="middle">'
                   'wall seconds (start-up included)</text>')
        out.append(f'<text x="16" y="{(top + bottom) / 2}" text-anchor="middle" '
                   f'transform="rotate(-90 16 {(top + bottom) / 2})">relMSE</text>')
        return "\n".join(out)

    def hline(self, y: float) -> str:
        return (f'<line x1="{self.LEFT}" y1="{self.py(y):.1f}" x2="{self.WIDTH - self.RIGHT}" '
                f'y2="{self.py(y):.1f}" stroke="#999" stroke-dasharray="1,3"/>')

    def polyline(self, xs: list[float], ys: list[float], color: str, dash: str) -> str:
        pts = " ".join(f"{self.px(x):.1f},{self.py(y):.1f}" for x, y in zip(xs, ys) if x > 0 and y > 0)
        dashing = f' stroke-dasharray="{dash}"' if dash else ""
        return f'<polyline points="{pts}" fill="none" stroke="{color}" stroke-width="1.6"{dashing}/>'


def legend(entries: list[tuple[str, str, str]], axes: LogAxes) -> str:
    x = axes.WIDTH - axes.RIGHT + 12
    out = []
    for i, (label, color, dash) in enumerate(entries):
        y = axes.TOP + 14 + 18 * i
        dashing = f' stroke-dasharray="{dash}"' if dash else ""
        out.append(f'<line x1="{x}" y1="{y - 4}" x2="{x + 24}" y2="{y - 4}" stroke="{color}" stroke-width="2"'
                   f'{dashing}/>')
        out.append(f'<text x="{x + 30}" y="{y}">{label}</text>')
    return "\n".join(out)
