"""Markdown tables of the convergence benchmark: time to each target relMSE with ratios to
Cycles, the references, the online error estimate against the true error, and per scene the
image each curve had at each time budget."""

from __future__ import annotations

import math
import os
import platform
from dataclasses import dataclass

import numpy as np

from .metrics import TARGETS, Curve, Reference
from .scenes import SETTING_NOTES, BenchScene


@dataclass
class SceneResult:
    scene: BenchScene
    haze: list[Curve]
    cycles: Curve | None
    cycles_vs_haze: Curve | None
    haze_ref: Reference
    cycles_ref: Reference | None
    load: str  # machine load when the scene's measurements started


def fmt(value: float, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:.{digits}g}"


def budget_table(result: SceneResult, budgets: list[float]) -> list[str]:
    """Markdown rows: per budget and curve, the last image available by then."""
    rows = ["| budget s | curve | seconds | spp | relMSE | RMSE | Haze's estimate |",
            "|---:|---|---:|---:|---:|---:|---:|"]
    curves = result.haze + [c for c in (result.cycles, result.cycles_vs_haze) if c is not None]
    for budget in budgets:
        for curve in curves:
            i = curve.at_budget(budget)
            if i is None:
                rows.append(f"| {budget:g} | {curve.label} | - | - | - | - | - |")
                continue
            rows.append(f"| {budget:g} | {curve.label} | {curve.seconds[i]:.2f} | {curve.spp[i]} | "
                        f"{fmt(curve.relmse[i])} | {fmt(curve.rmse[i])} | {fmt(curve.estimate[i])} |")
    return rows


def time_cell(curve: Curve, target: float) -> tuple[str, float]:
    seconds, extrapolated = curve.time_to(target)
    return (fmt(seconds) + ("*" if extrapolated else "")), seconds


def summary_table(results: list[SceneResult]) -> list[str]:
    """Markdown rows: time to relMSE 1e-2 and 1e-3 per curve, with and without start-up, and
    ratios to Cycles."""
    head = "| scene | curve | start-up s |"
    line = "|---|---|---:|"
    for target in TARGETS:
        head += f" to {target:g} s | / Cycles | to {target:g} s, no start-up | / Cycles |"
        line += "---:|---:|---:|---:|"
    rows = [head, line]
    for result in results:
        for curve in result.haze + [c for c in (result.cycles,) if c is not None]:
            row = f"| {result.scene.name} | {curve.label} | {fmt(curve.startup, 2)} |"
            for target in TARGETS:
                row += _target_cells(curve, result.cycles, target)
            rows.append(row)
    return rows


def _target_cells(curve: Curve, cycles: Curve | None, target: float) -> str:
    text, seconds = time_cell(curve, target)
    net = seconds - (0.0 if math.isnan(curve.startup) else curve.startup)
    ratio = ratio_net = math.nan
    if cycles is not None:
        cycles_seconds, _ = cycles.time_to(target)
        cycles_net = cycles_seconds - (0.0 if math.isnan(cycles.startup) else cycles.startup)
        ratio, ratio_net = seconds / cycles_seconds, net / cycles_net
    star = "*" if text.endswith("*") else ""
    return f" {text} | {fmt(ratio, 2)} | {fmt(net)}{star} | {fmt(ratio_net, 2)} |"


def reference_rows(results: list[SceneResult]) -> list[str]:
    rows = ["| scene | Haze ref spp | Haze ref noise relMSE | Haze ref s | Cycles ref spp | "
            "Cycles ref noise relMSE | Cycles ref s | Cycles vs Haze: mean ratio R, G, B |",
            "|---|---:|---:|---:|---:|---:|---:|---|"]
    for r in results:
        h, c = r.haze_ref, r.cycles_ref
        ratio = "-"
        if c is not None:
            ratio = ", ".join(f"{x:.4f}" for x in c.mean.mean(axis=(0, 1)) / h.mean.mean(axis=(0, 1)))
        rows.append(f"| {r.scene.name} | {h.spp} | {fmt(h.noise_relmse, 2)} | {h.seconds:.0f} | "
                    f"{c.spp if c else '-'} | {fmt(c.noise_relmse, 2) if c else '-'} | "
                    f"{f'{c.seconds:.0f}' if c else '-'} | {ratio} |")
    return rows


def estimate_rows(results: list[SceneResult]) -> list[str]:
    """The online estimates against the true relMSE along each scene's default Haze curve."""
    rows = ["| scene | setting | spp | true relMSE | Haze's estimate | true / estimate |",
            "|---|---|---:|---:|---:|---:|"]
    for result in results:
        if not result.haze:
            continue
        curve = result.haze[0]
        spp = np.asarray(curve.spp)
        wanted = [n for n in (4, 16, 64, 256, 1024) if spp.max() >= n / 2]
        picks = sorted({int(np.argmin(np.abs(spp - n))) for n in wanted})
        for i in picks:
            true = curve.relmse[i]
            rows.append(f"| {result.scene.name} | {curve.label} | {curve.spp[i]} | {fmt(true)} | "
                        f"{fmt(curve.estimate[i])} | {fmt(true / curve.estimate[i], 2)} |")
    return rows


def machine_line() -> str:
    load = os.getloadavg()
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
            f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


def report(results: list[SceneResult], budgets: list[float], command: str, load_before: str) -> str:
    lines = [f"Command: `{command}`", "", f"Machine at start: {load_before}", "",
             f"Machine at end: {machine_line()}", "",
             "Times are wall seconds from the start of each render (start-up included); the "
             "'no start-up' columns subtract each curve's fitted fixed cost. * = extrapolated "
             "along relMSE ~ 1/(t - start-up) past the last measured point.", "",
             "## Time to relMSE", ""]
    lines += summary_table(results) + ["", "## References", ""] + reference_rows(results)
    lines += ["", "## Online error estimate against the true relMSE", ""] + estimate_rows(results)
    lines += ["", "Settings: " + "; ".join(f"{k}: {v}" for k, v in SETTING_NOTES.items()), ""]
    for result in results:
        lines += ["", f"## {result.scene.name}: {result.scene.description}", "",
                  f"Measured from: {result.load}", ""]
        lines += budget_table(result, budgets)
    return "\n".join(lines) + "\n"
