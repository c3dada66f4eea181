"""The SIMD next-event vertices (renderer.integrator.nee_batch) against the scalar path.

Deterministic: both sides get the same random numbers, so they must agree to rounding
(the SIMD loop uses branch-free maths with the same series, and exp(-x) by a series where
the scalar path calls libm: a few units in the last place). The image test renders the same
paths both ways; shadow rays are stored in float32, so the images agree to float32 rounding.
"""

import llvmlite.binding as llvm
import numba
import numpy as np
import pytest
from numba import njit

from examples.scenes import cornell_box, cornell_fog, fog
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator import config as K
from renderer.integrator import nee_batch as NB
from renderer.integrator.dims import SEG_FREE_FLIGHT, SEG_LIGHT, SEG_VERTEX
from renderer.integrator.wavefront import Tracer
from renderer.kernels import JIT_OPTIONS
from renderer.kernels.rng import hashed_uniform, path_key
from renderer.kernels.vecmath import dot, madd, max3, mul, scale
from renderer.lights.sample import connect_light, light_point
from renderer.media.homogeneous import segment
from renderer.media.medium import sample_segment
from renderer.media.nee import nee_vertex_on
from renderer.media.spectral import channel_probabilities
from renderer.media.stack_phase import sample_phase
from renderer.media.table import P_G
from renderer.phase.hg import hg_eval
from renderer.scene import Medium


@njit(cache=True)
def _requests(nb, lt, md, stack, o, d, tmax, beta, light, g, use_eq, roulette, seed):
    """Record request j for ray (o[j], d[j], tmax[j]) with path key j, dimension 0, as
    shade_media does."""
    for j in range(o.shape[0]):
        _, ss, st, _, _ = segment(md, stack, tmax[j])
        NB.record(nb, j, j, path_key(seed, j, 0), 0, lt, light[j], (o[j, 0], o[j, 1], o[j, 2]),
                  (d[j, 0], d[j, 1], d[j, 2]), tmax[j], (beta[j, 0], beta[j, 1], beta[j, 2]), ss, st, g,
                  use_eq[j], roulette[j])


@njit(cache=True)
def _scalar(lt, md, stack, o, d, tmax, beta, light, g, use_eq, seed, mis, out):
    """The scalar path's vertex, connection and contribution (media_stage._medium_nee)."""
    for j in range(o.shape[0]):
        key = path_key(seed, j, 0)
        oo = (o[j, 0], o[j, 1], o[j, 2])
        dd = (d[j, 0], d[j, 1], d[j, 2])
        bb = (beta[j, 0], beta[j, 1], beta[j, 2])
        lp = light_point(lt, light[j], hashed_uniform(key, SEG_LIGHT + 1),
                         hashed_uniform(key, SEG_LIGHT + 2))
        t, wn, dim = nee_vertex_on(segment(md, stack, tmax[j]), oo, dd, tmax[j], lp, bb, key, SEG_VERTEX,
                                   use_eq[j], False)
        x = (oo[0] + t * dd[0], oo[1] + t * dd[1], oo[2] + t * dd[2])
        wi, dist, le, pdf, _ = connect_light(lt, light[j], lp, x, hashed_uniform(key, dim),
                                             hashed_uniform(key, dim + 1))
        p_light = pdf * lt.pmf[light[j]]
        ph = hg_eval(g, dot(dd, wi))
        w = p_light * p_light / (p_light * p_light + ph * ph) if mis else 1.0
        live = max3(wn) > 0.0 and p_light > 0.0 and max3(le) > 0.0
        for k in range(3):
            out[k, j] = x[k]
            out[3 + k, j] = wi[k]
            out[7 + k, j] = bb[k] * wn[k] * le[k] * ph * w / p_light if live else 0.0
        out[6, j] = dist * 0.9999


@njit(cache=True)
def _scalar_path(md, stack, o, d, tmax, beta, roulette, seed, out):
    """The scalar path's own free flight, phase sample and Russian roulette (shade_media):
    state, dim, beta, y, direction, pdf in nee_batch.path_update's order."""
    for j in range(o.shape[0]):
        key = path_key(seed, j, 0)
        oo = (o[j, 0], o[j, 1], o[j, 2])
        dd = (d[j, 0], d[j, 1], d[j, 2])
        bb = (beta[j, 0], beta[j, 1], beta[j, 2])
        t, scattered, w, _, dim = sample_segment(md, stack, segment(md, stack, tmax[j]), tmax[j],
                                                 channel_probabilities(bb, False), key, SEG_FREE_FLIGHT)
        bb = mul(bb, w)
        state = NB.PASSED
        y = madd(oo, dd, t)
        wi, pdf = (0.0, 0.0, 0.0), 0.0
        if max3(bb) <= 0.0:
            state = NB.DEAD
        elif scattered:
            wi, pw, pdf = sample_phase(md, stack, y, dd, hashed_uniform(key, dim),
                                       hashed_uniform(key, dim + 1), hashed_uniform(key, dim + 2))
            bb = mul(bb, pw)
            dim += 3
            state = NB.SCATTERED
            if roulette[j]:
                keep = min(1.0, max3(bb))
                if keep <= 0.0 or hashed_uniform(key, dim) >= keep:
                    state = NB.DEAD
                else:
                    bb = scale(bb, 1.0 / keep)
                dim += 1
        out[0, j] = state
        out[1, j] = dim
        for k in range(3):
            out[2 + k, j] = bb[k]
            out[5 + k, j] = y[k]
            out[8 + k, j] = wi[k]
        out[11, j] = pdf


def _rays(cs, n, rng):
    """Rays inside the box (tmax up to past its walls, or infinite), some starting just below
    the ceiling light (y = 0.999) or behind it, most far from it (so both the solid-angle and
    the area branch run, and both sides of the light)."""
    lo, hi = cs.vertices.min(0), cs.vertices.max(0)
    o = lo + (hi - lo) * rng.random((n, 3))
    o[: n // 8, 1] = 0.999 - 1e-3 * rng.random(n // 8)
    o[n // 8: n // 4, 1] = 0.999 + 1e-3 * rng.random(n // 8)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    tmax = np.concatenate([rng.random(n - n // 16) * 3.0 + 1e-6, np.full(n // 16, 1e30)])
    beta = np.where(rng.random((n, 3)) < 0.1, 0.0, 0.2 + 0.8 * rng.random((n, 3)))
    return o, d, tmax, beta


@pytest.mark.parametrize("medium_kw, g", [
    ({}, 0.0),
    ({"sigma_a": (0.0, 0.05, 2.0), "sigma_s": (0.5, 0.0, 1e-4)}, 0.9),
    ({"sigma_a": (1e-3, 1e-3, 1e-3), "sigma_s": (30.0, 3.0, 0.3)}, -0.7),
])
@pytest.mark.parametrize("mis, with_transmittance", [(True, False), (False, False), (True, True)])
def test_batch_matches_the_scalar_connection(medium_kw, g, mis, with_transmittance):
    scene = cornell_box(8, 1, medium=Medium("m", "homogeneous", g=g, **medium_kw) if medium_kw else fog(g))
    cs = compile_scene(scene)
    lt = cs.lights
    stack = np.array([0, -1, -1, -1], np.int32)
    g = float(cs.media.params[0, P_G])  # as stored (float32), which the scalar phase sampling reads
    n = NB.CHUNK  # one full pass (record writes rows 0..CHUNK-1 unchecked)
    rng = np.random.default_rng(11)
    o, d, tmax, beta = _rays(cs, n, rng)
    light = rng.integers(0, len(lt.pmf), n).astype(np.int32)
    use_eq = rng.random(n) < 0.8
    nb = NB.NeeBatch().arrays()
    roulette = rng.random(n) < 0.5
    _requests(nb, lt, cs.media, stack, o, d, tmax, beta, light, g, use_eq, roulette, 3)
    NB.run(n, nb, mis, with_transmittance, False)
    ref = np.zeros((10, n))
    _scalar(lt, cs.media, stack, o, d, tmax, beta, light, g, use_eq, 3, mis, ref)
    if with_transmittance:  # what shadow_media would multiply in
        sigma_t = nb[0].reshape(NB.Q_ROWS, NB.CHUNK)[NB.Q_ST:NB.Q_ST + 3, :n]
        ref[7:] *= np.exp(-sigma_t * ref[6])
    r = nb[4].reshape(NB.R_ROWS, NB.CHUNK)
    got = r[:10, :n]
    live = ref[7:].max(axis=0) > 0.0
    assert 0.5 * n < live.sum() < n  # both kinds of request occur
    assert np.array_equal(got[7:].max(axis=0) > 0.0, live)
    scale = np.abs(ref[:, live]).max(axis=1, keepdims=True).clip(1e-300)
    # Relative to each quantity's scale: wi components near 0 carry the direction's rounding.
    assert np.max(np.abs(got[:, live] - ref[:, live]) / scale) < 1e-11
    assert np.max(np.abs(got[7:, live] - ref[7:, live]) / ref[7:, live].clip(1e-300)) < 1e-10

    # The path's own segment: same fate, dimension, throughput, point, direction and pdf.
    ref = np.zeros((12, n))
    _scalar_path(cs.media, stack, o, d, tmax, beta, roulette, 3, ref)
    got = r[[NB.R_STATE, NB.R_DIM, *range(NB.R_BETA, NB.R_BETA + 3), *range(NB.R_Y, NB.R_Y + 3),
             *range(NB.R_DIR, NB.R_DIR + 3), NB.R_PDF], :n]
    np.testing.assert_array_equal(got[0], ref[0])
    for state in (NB.DEAD, NB.PASSED, NB.SCATTERED):
        assert (ref[0] == state).sum() > n // 50, state  # every fate occurs
    alive = ref[0] != NB.DEAD
    np.testing.assert_array_equal(got[1, alive], ref[1, alive])
    scattered = ref[0] == NB.SCATTERED
    for rows, which in (((2, 3, 4), alive), ((5, 6, 7, 8, 9, 10, 11), scattered)):
        rows = list(rows)
        scale = np.abs(ref[rows][:, which]).max(axis=1, keepdims=True).clip(1e-300)
        assert np.max(np.abs(got[rows][:, which] - ref[rows][:, which]) / scale) < 1e-11


def test_render_is_the_same_with_and_without_batching():
    for scene in (cornell_fog(24, 1, g=0.5),
                  cornell_box(24, 1, medium=Medium("m", "homogeneous", sigma_a=(0.0, 0.3, 1.0),
                                                   sigma_s=(1.0, 0.2, 0.0), g=-0.3))):
        cs = compile_scene(scene)
        images = []
        for batched in (1, 0):
            tracer = Tracer(cs, scene.integrator)
            tracer.cfg[K.CFG_NEE_BATCH] = batched
            film = Film(cs.width, cs.height)
            tracer.trace(film, 0, 4, 5)
            images.append(film.sum)
        assert images[0].sum() > 0.0
        np.testing.assert_allclose(images[0], images[1], rtol=1e-5, atol=0.0)


def _targets_avx2() -> bool:
    features = llvm.get_host_cpu_features()
    return numba.config.CPU_NAME in (None, "host") and bool(features.get("avx2"))


@pytest.mark.skipif(not _targets_avx2(), reason="the speed claim is for AVX2/AVX-512 hosts: for plain "
                    "SSE2 (NUMBA_CPU_NAME=generic) LLVM's cost model keeps the loops scalar")
def test_the_batch_loops_compile_to_simd():
    """LLVM vectorises the loops only when nothing in them defeats it (a select between two
    loads, a call, an access it cannot prove disjoint from the stores): a regression would
    keep the images right and lose the speed silently, so check the vector types in the IR."""
    options = {**JIT_OPTIONS, "cache": False}
    nb = NB.NeeBatch().arrays()
    stages = ((NB.segments, (16, nb, False)), (NB.vertices, (16, nb)), (NB.connections, (16, nb, True, True)),
              (NB.advance, (16, nb)))
    for stage, args in stages:
        fresh = njit(**options)(stage.py_func)
        fresh(*args)
        ir = "".join(fresh.inspect_llvm().values())
        assert "x double>" in ir, stage.__name__
