"""The medium stack of a path: which media overlap at the path's current position.

A stack is one int32 row of MAX_STACK medium ids (the scene's limit, renderer.scene),
filled from slot 0 with no holes and -1 in the empty slots. The integrator pushes a medium
when a ray enters a medium's mesh and removes it on leaving. The same id may be present
twice (two overlapping meshes carrying the same medium add their coefficients, as two
Cycles objects do); removing takes away one occurrence.
"""

from renderer.kernels import inline_kernel
from renderer.media.table import emits, is_grid
from renderer.scene import MAX_STACK

EMPTY = -1


@inline_kernel
def stack_is_empty(stack):
    return stack[0] == EMPTY


@inline_kernel
def stack_size(stack):
    n = 0
    while n < MAX_STACK and stack[n] != EMPTY:
        n += 1
    return n


@inline_kernel
def stack_has_grid(mt, stack):
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        if is_grid(mt, m):
            return True
    return False


@inline_kernel
def stack_has_emission(mt, stack):
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        if emits(mt, m):
            return True
    return False


@inline_kernel
def stack_push(stack, m):
    """Add medium m in place. A full stack drops it (returns False): a fifth overlapping
    medium is ignored rather than crashing a render."""
    for i in range(MAX_STACK):
        if stack[i] == EMPTY:
            stack[i] = m
            return True
    return False


@inline_kernel
def stack_remove(stack, m):
    """Remove the last occurrence of medium m in place, keeping the slots packed.
    Returns False (and changes nothing) when m is not on the stack."""
    for i in range(MAX_STACK - 1, -1, -1):
        if stack[i] == m:
            for j in range(i, MAX_STACK - 1):
                stack[j] = stack[j + 1]
            stack[MAX_STACK - 1] = EMPTY
            return True
    return False
