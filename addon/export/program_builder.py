"""Assembles a shader program (renderer.shading.program) while the node graph is walked:
registers, instructions, tables, and the attributes and images the program reads.

Operands are registers (Reg); constants are folded into the initial register file, so an
instruction only ever names registers, as in Cycles' SVM stack."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderer.shading.names import MATH_OPS
from renderer.shading.program import INSTR, OP, ShaderProgram

from .node_values import TRIPLE_TYPES


@dataclass(frozen=True)
class Reg:
    """`width` consecutive registers from `index` (1: a scalar, 3: a vector or colour)."""

    index: int
    width: int


MATH = {name: code for code, name in enumerate(MATH_OPS)}


class ProgramBuilder:
    def __init__(self) -> None:
        self.registers: list[float] = []
        self.code: list[list[int]] = []
        self.data: list[float] = []
        self.attributes: list[str] = []
        self.images: list[str] = []
        self._consts: dict[tuple, Reg] = {}
        self._emitted: dict[tuple, Reg] = {}  # identical instructions are emitted once

    # ---------------------------------------------------------------- registers
    def alloc(self, width: int) -> Reg:
        reg = Reg(len(self.registers), width)
        self.registers.extend([0.0] * width)
        return reg

    def const(self, value) -> Reg:
        values = tuple(float(v) for v in np.atleast_1d(np.asarray(value, np.float64)).ravel())
        if values not in self._consts:
            reg = self.alloc(len(values))
            self.registers[reg.index:reg.index + reg.width] = list(values)
            self._consts[values] = reg
        return self._consts[values]

    def emit(self, op: str, width: int, *sources: Reg | None, i0: int = 0, i1: int = 0, i2: int = 0,
             dst: Reg | None = None) -> Reg:
        """Append one instruction writing `width` registers (a new Reg unless dst is given).
        Without dst, an instruction identical to an earlier one returns that one's result
        (a closure evaluated for both faces asks for the same values twice)."""
        regs = [s.index if s is not None else 0 for s in sources] + [0] * (5 - len(sources))
        key = (op, width, *regs, int(i0), int(i1), int(i2))
        if dst is None and key in self._emitted:
            return self._emitted[key]
        new = dst is None
        dst = dst or self.alloc(width)
        self.code.append([OP[op], dst.index, *regs, int(i0), int(i1), int(i2)])
        if new:
            self._emitted[key] = dst
        return dst

    # ---------------------------------------------------------------- inputs of the program
    def attribute(self, name: str, width: int) -> Reg:
        if name not in self.attributes:
            self.attributes.append(name)
        return self.emit("attribute", 3, i0=self.attributes.index(name), i1=width)

    def image(self, name: str) -> int:
        if name not in self.images:
            self.images.append(name)
        return self.images.index(name)

    def table(self, values: np.ndarray) -> int:
        start = len(self.data)
        self.data.extend(float(v) for v in np.asarray(values, np.float64).ravel())
        return start

    # ---------------------------------------------------------------- conversions
    def widen(self, reg: Reg) -> Reg:
        return reg if reg.width == 3 else self.emit("combine", 3, reg, reg, reg)

    def convert(self, reg: Reg, from_type: str, to_type: str) -> Reg:
        """Blender's implicit socket conversions, as node_values.convert."""
        if to_type in TRIPLE_TYPES:
            return self.widen(reg)
        if reg.width == 1:
            return reg
        if from_type == "RGBA":
            return self.emit("rgb_to_bw", 1, reg)
        total = self.component_sum(reg)
        return self.emit("math", 1, total, self.const(1.0 / 3.0), self.const(0.0), i0=MATH["MULTIPLY"])

    def component(self, reg: Reg, k: int) -> Reg:
        return Reg(reg.index + k, 1)

    def component_sum(self, reg: Reg) -> Reg:
        xy = self.emit("math", 1, self.component(reg, 0), self.component(reg, 1), self.const(0.0),
                       i0=MATH["ADD"])
        return self.emit("math", 1, xy, self.component(reg, 2), self.const(0.0), i0=MATH["ADD"])

    # ---------------------------------------------------------------- result
    def build(self, bindings: list[tuple[int, int, int, int, int]]) -> ShaderProgram:
        code = np.array(self.code, np.int32).reshape(-1, INSTR.size)
        return ShaderProgram(code, np.array(self.registers, np.float32),
                             np.array(bindings, np.int32).reshape(-1, 5), np.array(self.data, np.float32),
                             list(self.attributes), list(self.images))

