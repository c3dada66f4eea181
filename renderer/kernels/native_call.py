"""Call a compiled numba function through its machine-code address, so that the caller's
compile does not include the callee's.

Why: when a kernel calls another numba function, numba links the callee's whole LLVM module
into the caller's and LLVM optimises and generates code for the union again, at every
level of the call tree. The shader interpreter (renderer.shading.interpreter.run_program,
thousands of lines of LLVM) was optimised again inside each of about twenty kernels that
reach it: 15-40 s each, over 15 CPU minutes for a scene's first render. Called through its
address, it is compiled once, and each caller compiles one indirect call.

    address = native_address(run_program, *example_args)   # in Python, per process
    call_native(address, (arg0, arg1, ...))                 # in a kernel

The address is a process's own (where the compiled code was loaded), so it is computed at
run time in every process and passed to the kernels as an int64 argument; it is never
cached or pickled. The callee's argument types are those numba gives the example
arguments; the caller must pass exactly those types, which call_native cannot check (the
callee is not known when the caller compiles). What it does check: numba types a Python
float as float64, an int as int64 and a bool as bool, so any other scalar in the arguments
(a float32 from an array element, an int32 index) is a type error at compile time, not a
silent reinterpretation of bits. Arrays and tuples carry their own types through.

The call uses numba's own calling convention (a return slot, an exception slot, then every
argument flattened by its data model) and propagates an exception status like a direct call.
"""

from __future__ import annotations

from numba.core import cgutils, types
from numba.core.errors import TypingError
from numba.extending import intrinsic

_SCALARS_ALLOWED = (types.int64, types.float64, types.boolean)


def native_address(dispatcher, *args) -> int:
    """The address of `dispatcher`'s compiled code for the numba types of `args` (compiling
    or loading it from the cache first). Valid in this process only."""
    sig = tuple(dispatcher.typeof_pyval(a) for a in args)
    dispatcher.compile(sig)
    compiled = dispatcher.overloads[sig]
    return int(compiled.library.get_pointer_to_function(compiled.fndesc.llvm_func_name))


def _check_scalars(ty, where: str) -> None:
    if isinstance(ty, types.BaseTuple):
        for k, item in enumerate(ty.types):
            _check_scalars(item, f"{where}[{k}]")
    elif isinstance(ty, (types.Number, types.Boolean)) and ty not in _SCALARS_ALLOWED:
        raise TypingError(f"call_native: argument {where} is {ty}; pass int64, float64 or bool "
                          "(the types numba gives Python scalars, which the callee was compiled for)")


@intrinsic
def call_native(typingctx, address, args):
    """Call the numba function at `address` (native_address) with the tuple `args`; returns
    None."""
    if not isinstance(address, types.Integer):
        raise TypingError(f"call_native: the address must be an integer, not {address}")
    if not isinstance(args, types.BaseTuple):
        raise TypingError(f"call_native: the arguments must be a tuple, not {args}")
    # A literal (a constant in the caller) has its type's data model: pass it as that type.
    argtypes = tuple(types.unliteral(ty) for ty in args.types)
    for k, ty in enumerate(argtypes):
        _check_scalars(ty, str(k))

    def codegen(context, builder, sig, llargs):
        addr, packed = llargs
        values = [builder.extract_value(packed, k) for k in range(len(argtypes))]
        call_conv = context.call_conv
        fnty = call_conv.get_function_type(types.none, argtypes)
        fn = builder.inttoptr(addr, fnty.as_pointer())
        ret_slot = cgutils.alloca_once(builder, fnty.args[0].pointee)
        builder.store(cgutils.get_null_value(fnty.args[0].pointee), ret_slot)
        exc_slot = cgutils.alloca_once(builder, fnty.args[1].pointee)
        flat = list(call_conv._get_arg_packer(argtypes).as_arguments(builder, values))
        code = builder.call(fn, [ret_slot, exc_slot] + flat)
        status = call_conv._get_return_status(builder, code, builder.load(exc_slot))
        with cgutils.if_unlikely(builder, status.is_error):
            call_conv.return_status_propagate(builder, status)
        return context.get_dummy_value()

    return types.none(address, args), codegen

