"""The last stage of a batch: its finished paths added to the film."""

import numpy as np

from ..kernels import kernel
from .paths import ALPHA, AOV_COUNT, AOV_FIRST, LIGHT_AOV_FIRST


@kernel
def splat(n, L, slots, sums):
    """Add paths 0..n-1 of a batch (radiance L[pid, :3], pixel slots.pixel[pid]) to a
    Film's sums (film.FilmSums): per-pixel sum, sum of squares, count, the odd samples' sum
    and count (slots.half[pid] 1 for odd), and alpha = 1 - the path's transparency
    L[pid, ALPHA]. A non-finite path value (a bug, never expected) is counted and added as
    0, so one bad path cannot ruin an image but cannot pass unnoticed either. sums.aov
    (P, AOV_COUNT) gets the passes' columns L[pid, AOV_FIRST:], (P, AOV_COUNT +
    LIGHT_AOV_COUNT) also the light passes' L[pid, LIGHT_AOV_FIRST:], or is empty (0 rows)
    when no pass was requested."""
    pixel_of_pid, half_of_pid = slots.pixel, slots.half
    film_sum, film_sq, film_n, film_odd = sums.sum, sums.sq, sums.n, sums.odd
    film_nonfinite, film_alpha, film_aov = sums.nonfinite, sums.alpha, sums.aov
    aovs = film_aov.shape[0] > 0
    for i in range(n):
        px = pixel_of_pid[i]
        for c in range(3):
            v = L[i, c]
            if not np.isfinite(v):
                film_nonfinite[0] += 1
                v = 0.0
            film_sum[px, c] += v
            film_sq[px, c] += v * v
            if half_of_pid[i]:
                film_odd[px, c] += v
        film_n[px] += 1
        film_odd[px, 3] += half_of_pid[i]
        film_alpha[px] += 1.0 - L[i, ALPHA]
        if aovs:
            for c in range(AOV_COUNT):
                film_aov[px, c] += L[i, AOV_FIRST + c]
            for c in range(film_aov.shape[1] - AOV_COUNT):
                film_aov[px, AOV_COUNT + c] += L[i, LIGHT_AOV_FIRST + c]
