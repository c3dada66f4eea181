"""Kernels whose float32 arithmetic is exactly the C++ it mirrors: one rounding per
operation, fused multiply-adds only where written (fma32).

Why: the shared kernels compile with fastmath "contract", so LLVM may fuse any a * b + c,
and Haze's shading otherwise runs in float64. Where Cycles' float32 round-off decides a
result that is then amplified (Noise Texture's distortion moves a point that is offset by
~150 before the colour's noise, where one float32 step is 1.5e-5), the rounding itself must
match: operands typed float32 (numpy float32 constants), no contraction, and llvm.fma.f32
where Cycles' compiled kernel has a vfmadd (renderer.shading.perlin32).

The `fastmath` flags are set per instruction, so an exact kernel keeps its roundings when
LLVM inlines it into a fastmath caller.
"""

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from renderer.kernels import exact_kernel

__all__ = ["exact_kernel", "fma32"]


@intrinsic
def fma32(typingctx, a, b, c):
    """a * b + c rounded once to float32 (llvm.fma.f32: vfmadd on x86-64 with FMA, libm's
    fmaf without); the arguments are converted to float32 first."""
    if not all(isinstance(t, (types.Float, types.Integer)) for t in (a, b, c)):
        return None
    sig = types.float32(a, b, c)

    def codegen(context, builder, signature, args):
        values = [context.cast(builder, v, t, types.float32) for v, t in zip(args, signature.args)]
        f32 = ir.FloatType()
        fma = builder.module.declare_intrinsic("llvm.fma", [f32], ir.FunctionType(f32, [f32, f32, f32]))
        return builder.call(fma, values)

    return sig, codegen
