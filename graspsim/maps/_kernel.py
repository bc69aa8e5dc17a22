"""Compiled collision sweep of the surface-to-voxel generator (numba).

Geometry of the test
--------------------
For one closing line (grasp point GP, closing axis u, pre-grasp opening o) the
gripper's roll phi about u and its contact depth d (distance of the contact from the
fingertip along the pad) are swept. A point q of the object has line-frame
coordinates s = (q-GP).u, a = (q-GP).e1, b = (q-GP).e2 (e1 x e2 = u). At roll phi the
wrist axes are x = u, z = cos(phi) e1 + sin(phi) e2, y = z x x, so q has wrist
coordinates x = s, y = a sin(phi) - b cos(phi), z_w = t + fingertip_z - d with
t = a cos(phi) + b sin(phi).

The gripper is three nested "columns": each finger's footprint in (x, y) lies inside
its jaw's, each jaw's inside the housing's, and everything behind the housing is the
robot arm. A point in the footprint of part k therefore collides iff its z_w is below
part k's top face, i.e. iff t + off_k <= d with off_k = fingertip_z - top_k. One
minimum per roll answers all depths: pose (phi, d) collides iff min_q (t_q + off) <= d.

Exactness
---------
The object is represented by surface samples on two levels. Each coarse sample c
stands for the surface patch nearest to it; from its fine children the kernel knows
the patch's tangential radius ``rt`` and its height ``h`` along c's normal n, so along
any unit direction e the patch reaches at most rt * sqrt(1 - (n.e)^2) + h |n.e| + f
from c (f = the fine cover radius). Coarse tests grow each part by exactly that reach
(small where the surface is tangent to a part's face, the common near miss): no coarse
hit means no collision; a coarse sample inside a part (it lies on the surface) means a
certain collision. Depths in between are refined with the fine children, grown by f:
exact except that poses within f of touching count as colliding (conservative).

Loops run with the rolls innermost so that numba vectorises them (element-wise minima
over the roll axis; horizontal min-reductions do not vectorise).

Compilation
-----------
Each kernel is compiled once, for the one signature in ``SIGNATURES`` (float32 samples
and frames, C-contiguous arrays), and cached on disk (``cache=True``); the entry points
release the GIL and work on a range of line chunks, so :mod:`graspsim.maps.kernels`
runs them on Python threads. Plain (non-``parallel``) functions compile in about half
the time of numba's parallel loops; :func:`graspsim.maps.kernels.ensure_compiled`
compiles them in order and says so on the first run.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

from graspsim.maps._assemble_kernel import assemble_rows  # compiled and cached with the sweep (SIGNATURES)

__all__ = ["sweep_lines", "assemble_rows", "SIGNATURES"]

_f4, _i4, _i8, _u1 = types.float32, types.int32, types.int64, types.uint8
_V, _M = _f4[::1], _f4[:, ::1]  # float32 vector (n,), matrix (n, k), C order

# A large finite sentinel: fastmath lets LLVM assume there are no infinities.
_BIG = np.float32(1e9)
_ZERO = np.float32(0.0)


@njit(cache=True, fastmath=True)
def _xoff(s, lo, hi, off):
    return off if (s >= lo and s <= hi) else _BIG


@njit(cache=True, fastmath=True)
def _cluster_near(cc, r, cx, gp, u, e1, e2, ho, fp, fmargin, c1, s1, dlim):
    """Whether any sample of a cluster (within r of cc, rt + hn at most cx) can have a
    patch value at or below ``dlim`` at the roll (c1, s1) (see :func:`_gather`)."""
    dx = cc[0] - gp[0]
    dy = cc[1] - gp[1]
    dz = cc[2] - gp[2]
    sc = abs(dx * u[0] + dy * u[1] + dz * u[2])
    ac = dx * e1[0] + dy * e1[1] + dz * e1[2]
    bc = dx * e2[0] + dy * e2[1] + dz * e2[2]
    mc = cx + fmargin  # bounds a sample's x growth
    grow = np.float32(2.0) * cx + fmargin  # bounds its patch's reach along the wrist's y and z
    tlo = ac * c1 + bc * s1 - r - grow  # the least t - m_t of any sample of the cluster
    ylo = abs(ac * s1 - bc * c1) - r - grow
    slo = sc - r
    shi = sc + r
    near = shi >= ho + fp[0, 0] - mc and slo <= ho + fp[0, 1] + mc and ylo <= fp[0, 2] and tlo + fp[0, 3] <= dlim
    near = near or (shi >= ho + fp[1, 0] - mc and slo <= ho + fp[1, 1] + mc and ylo <= fp[1, 2]
                    and tlo + fp[1, 3] <= dlim)
    return near or (slo <= fp[2, 1] + mc and ylo <= fp[2, 2] and tlo + fp[2, 3] <= dlim)


@njit(cache=True, fastmath=True)
def _gather(Q, NQ, RT, HN, order, cstart, CC, CR, CX, gp, u, e1, e2, ho, fp, fmargin, reach2, single, c1, s1,
            dlim, idx, ca, cb, cna, cnb, cns, crt, chn, oF, oJ, oH, xF, xJ, xH):
    """Collect the coarse samples that can touch the gripper on this line and their
    per-sample data; returns the count. fp rows finger/jaw/housing:
    (x_inner, x_outer, half_width_y, off, unused); sided parts sit at |x| in
    [o/2 + x_inner, o/2 + x_outer], the housing at |x| <= x_outer.

    single: the line is swept at one roll only (cos c1, sin s1): a sample whose patch
    values there (conservative and exact, as :func:`_roll_minima` computes them) both
    exceed ``dlim`` (above the deepest depth) changes no answer -- every depth is below
    it, and the fine level descends only from values at or below a depth -- and is left
    out; and whole clusters of samples are (cluster c: ``order[cstart[c]:cstart[c + 1]]``,
    within CR[c] of CC[c], rt + hn at most CX[c]) where bounds over the cluster show no
    sample's value there can be at or below ``dlim``. The samples kept are the same;
    every later use of them takes minima, which their order does not change."""
    n = 0
    for c in range(CR.shape[0] if single else 1):
        k0, k1 = 0, Q.shape[0]
        if single:
            if not _cluster_near(CC[c], CR[c], CX[c], gp, u, e1, e2, ho, fp, fmargin, c1, s1, dlim):
                continue
            k0, k1 = cstart[c], cstart[c + 1]
        for k in range(k0, k1):
            i = order[k] if single else k
            dx = Q[i, 0] - gp[0]
            dy = Q[i, 1] - gp[1]
            dz = Q[i, 2] - gp[2]
            s = dx * u[0] + dy * u[1] + dz * u[2]
            a = dx * e1[0] + dy * e1[1] + dz * e1[2]
            b = dx * e2[0] + dy * e2[1] + dz * e2[2]
            ns = NQ[i, 0] * u[0] + NQ[i, 1] * u[1] + NQ[i, 2] * u[2]
            rt = RT[i]
            hn = HN[i]
            ans = abs(ns)
            # |n x e_x| <= |n.e1| + |n.e2|
            na_ = abs(NQ[i, 0] * e1[0] + NQ[i, 1] * e1[1] + NQ[i, 2] * e1[2])
            nb_ = abs(NQ[i, 0] * e2[0] + NQ[i, 1] * e2[1] + NQ[i, 2] * e2[2])
            mx = rt * min(na_ + nb_, np.float32(1.0)) + hn * ans + fmargin
            sa = abs(s)
            fo = _xoff(sa, ho + fp[0, 0] - mx, ho + fp[0, 1] + mx, fp[0, 3])
            jo = _xoff(sa, ho + fp[1, 0] - mx, ho + fp[1, 1] + mx, fp[1, 3])
            hh = _xoff(sa, np.float32(-1.0), fp[2, 1] + mx, fp[2, 3])
            rho2 = a * a + b * b
            if fo < _BIG or (jo < _BIG and rho2 >= reach2[1]) or (hh < _BIG and rho2 >= reach2[2]):
                na = NQ[i, 0] * e1[0] + NQ[i, 1] * e1[1] + NQ[i, 2] * e1[2]
                nb = NQ[i, 0] * e2[0] + NQ[i, 1] * e2[1] + NQ[i, 2] * e2[2]
                ef = _xoff(sa, ho + fp[0, 0], ho + fp[0, 1], fp[0, 3])
                ej = _xoff(sa, ho + fp[1, 0], ho + fp[1, 1], fp[1, 3])
                eh = _xoff(sa, np.float32(-1.0), fp[2, 1], fp[2, 3])
                if single and _patch_value(a, b, na, nb, ans, rt, hn, fo, jo, hh, c1, s1, fp[0, 2], fp[1, 2],
                                           fp[2, 2], fmargin) > dlim \
                        and _patch_value(a, b, na, nb, ans, _ZERO, _ZERO, ef, ej, eh, c1, s1, fp[0, 2], fp[1, 2],
                                         fp[2, 2], _ZERO) > dlim:
                    continue
                idx[n] = i
                ca[n] = a
                cb[n] = b
                cna[n] = na
                cnb[n] = nb
                cns[n] = ans
                crt[n] = rt
                chn[n] = hn
                oF[n] = fo
                oJ[n] = jo
                oH[n] = hh
                xF[n] = ef
                xJ[n] = ej
                xH[n] = eh
                n += 1
    return n


@njit(cache=True, fastmath=True)
def _patch_value(a, b, na, nb, ns, rt, hn, f, jj, h, c, s, hyF, hyJ, hyH, fmargin):
    """Value t - m_t + off of a sample's surface patch at roll (c, s): the patch reaches
    m_y, m_t from the sample along the wrist's y and z axes (tangential radius rt,
    normal height hn, plus ``fmargin``); a point belongs to every part whose x and y
    ranges both contain it (x-membership is encoded in the offsets f, jj, h: _BIG when
    outside). sqrt(1 - ny^2) = |(nt, ns)| <= nt + ns, so no square roots."""
    y = abs(a * s - b * c)
    t = a * c + b * s
    ny = abs(na * s - nb * c)
    nt = abs(na * c + nb * s)
    my = rt * (nt + ns) + hn * ny + fmargin
    mt = rt * (ny + ns) + hn * nt + fmargin
    o = h if y <= hyH + my else _BIG
    o2 = jj if y <= hyJ + my else _BIG
    o = o2 if o2 < o else o
    o2 = f if y <= hyF + my else _BIG
    o = o2 if o2 < o else o
    return t - mt + o


@njit(cache=True, fastmath=True)
def _roll_minima(n, ca, cb, cna, cnb, cns, crt, chn, oF, oJ, oH, xF, xJ, xH, cr, sr,
                 hyF, hyJ, hyH, fmargin, vin, vex):
    """Per roll: vex = exact min of t + off; vin = its conservative lower bound."""
    R = cr.shape[0]
    for r in range(R):
        vin[r] = _BIG
        vex[r] = _BIG
    for k in range(n):
        for r in range(R):
            # conservative: the sample's patch grown by its anisotropic extent
            v = _patch_value(ca[k], cb[k], cna[k], cnb[k], cns[k], crt[k], chn[k], oF[k], oJ[k], oH[k], cr[r], sr[r],
                             hyF, hyJ, hyH, fmargin)
            vin[r] = v if v < vin[r] else vin[r]
            # exact: the sample itself (a surface point) with the exact footprints
            v = _patch_value(ca[k], cb[k], cna[k], cnb[k], cns[k], _ZERO, _ZERO, xF[k], xJ[k], xH[k], cr[r], sr[r],
                             hyF, hyJ, hyH, _ZERO)
            vex[r] = v if v < vex[r] else vex[r]


@njit(cache=True, fastmath=True)
def _line_coords(P, N, i, gp, u, e1, e2, rt, hn, ho, fp, margin):
    """Line-frame coordinates of sample ``i`` of (P, N): a, b, its normal's (e1, e2)
    components and |n.u|, and the x-footprint offsets of its patch (tangential radius
    rt, normal height hn, grown by ``margin``) for finger, jaw, housing."""
    dx = P[i, 0] - gp[0]
    dy = P[i, 1] - gp[1]
    dz = P[i, 2] - gp[2]
    sa = abs(dx * u[0] + dy * u[1] + dz * u[2])
    a = dx * e1[0] + dy * e1[1] + dz * e1[2]
    b = dx * e2[0] + dy * e2[1] + dz * e2[2]
    na = N[i, 0] * e1[0] + N[i, 1] * e1[1] + N[i, 2] * e1[2]
    nb = N[i, 0] * e2[0] + N[i, 1] * e2[1] + N[i, 2] * e2[2]
    ns = abs(N[i, 0] * u[0] + N[i, 1] * u[1] + N[i, 2] * u[2])
    mx = rt * min(abs(na) + abs(nb), np.float32(1.0)) + hn * ns + margin
    f = _xoff(sa, ho + fp[0, 0] - mx, ho + fp[0, 1] + mx, fp[0, 3])
    j = _xoff(sa, ho + fp[1, 0] - mx, ho + fp[1, 1] + mx, fp[1, 3])
    h = _xoff(sa, np.float32(-1.0), fp[2, 1] + mx, fp[2, 3])
    return a, b, na, nb, ns, f, j, h


@njit(cache=True, fastmath=True)
def _refine(n, idx, ca, cb, cna, cnb, cns, crt, chn, oF, oJ, oH, nu, cu, su, dhi, best,
            M, NM, RTM, HNM, mstart, F, NF, RTF, HNF, fstart, gp, u, e1, e2, ho, fp, fmargin, hit):
    """Fine-level minima ``best[j]`` of t - f + off for the ``nu`` uncertain rolls
    (cos cu[j], sin su[j]): descend from every coarse candidate whose patch value
    reaches that roll's deepest uncertain depth ``dhi[j]`` to its middle-level
    children (same patch test), and from those to their fine samples, each tested
    with its own cell's extent (tangential radius RTF, normal height HNF)."""
    hyF, hyJ, hyH = fp[0, 2], fp[1, 2], fp[2, 2]
    for j in range(nu):
        best[j] = _BIG
    for k in range(n):
        cnt = 0
        for j in range(nu):
            v = _patch_value(ca[k], cb[k], cna[k], cnb[k], cns[k], crt[k], chn[k], oF[k],
                             oJ[k], oH[k], cu[j], su[j], hyF, hyJ, hyH, fmargin)
            cnt += 1 if v <= dhi[j] else 0
        if cnt == 0:
            continue
        i = idx[k]
        for m in range(mstart[i], mstart[i + 1]):
            rt = RTM[m]
            hn = HNM[m]
            ma, mb, mna, mnb, mns, mf, mj, mh = _line_coords(M, NM, m, gp, u, e1, e2, rt, hn, ho,
                                                             fp, fmargin)
            if mh >= _BIG:
                continue
            cnt = 0
            for j in range(nu):
                v = _patch_value(ma, mb, mna, mnb, mns, rt, hn, mf, mj, mh, cu[j], su[j],
                                 hyF, hyJ, hyH, fmargin)
                cnt += 1 if v <= dhi[j] else 0
            if cnt == 0:
                continue
            for q in range(fstart[m], fstart[m + 1]):
                rtf = RTF[q]
                hnf = HNF[q]
                # the fine sample's own cell: exact up to its extent in each direction
                fa, fb, fna, fnb, fns, qf, qj, qh = _line_coords(F, NF, q, gp, u, e1, e2, rtf, hnf,
                                                                 ho, fp, _ZERO)
                if qh >= _BIG:
                    continue
                for j in range(nu):
                    v = _patch_value(fa, fb, fna, fnb, fns, rtf, hnf, qf, qj, qh, cu[j], su[j],
                                     hyF, hyJ, hyH, np.float32(0.0))
                    best[j] = v if v < best[j] else best[j]
            hit[0] += 1


@njit(cache=True, nogil=True, fastmath=True)
def sweep_lines(gp, u, e1, e2, half_open, Q, NQ, RT, HN, order, cstart, CC, CR, CX, M, NM, RTM, HNM, mstart,
                F, NF, RTF, HNF, fstart, fp, reach2, cos_r, sin_r, depths, fmargin, refine, need, free,
                n_refined, chunk0, chunk1, nchunk):
    """Collision sweep over lines x rolls x depths, for the lines of chunks
    ``chunk0 <= c < chunk1`` (chunk c holds lines c, c + nchunk, c + 2 nchunk, ...).

    gp, u, e1, e2: (L, 3) float32 line frames; half_open: (L,) pre-grasp opening / 2.
    Q, NQ: (Mc, 3) coarse samples and their normals; RT, HN: (Mc,) tangential radius
    and normal height of each sample's patch; order, cstart, CC, CR, CX: their spatial
    clusters (see :func:`_gather`). M, NM, RTM, HNM: the same for the middle
    level, ordered by coarse parent (parent i owns M[mstart[i]:mstart[i+1]]); F, NF:
    (Mf, 3) fine samples and normals ordered by middle parent (m owns
    F[fstart[m]:fstart[m+1]]), RTF, HNF: (Mf,) the extent of each fine sample's cell.
    fp: (3, 5) footprints; reach2: (3,)
    squared minimum distance from the closing axis at which jaws / housing can be hit.
    cos_r, sin_r: (R,) roll angles; depths: (D,) increasing contact depths [m].
    refine: resolve uncertain poses with the fine level (else they count as colliding).
    need: (L, R, D) uint8, the poses whose answer is wanted (the others may be left 0
    when finding them would need the fine level), or (1, 1, 1) for all.
    Writes free (L, R, D) = 1 for collision-free poses and n_refined (L,), the number
    of rolls that needed the fine level.
    """
    L = gp.shape[0]
    R = cos_r.shape[0]
    D = depths.shape[0]
    Mc = Q.shape[0]
    hyF, hyJ, hyH = fp[0, 2], fp[1, 2], fp[2, 2]
    all_needed = need.shape[0] == 1 and L != 1
    dlim = depths[D - 1] + np.float32(1e-6)  # a patch value above this answers no depth
    idx = np.empty(Mc, np.int32)
    buf = np.empty((13, Mc), np.float32)
    ca, cb, cna, cnb, cns, crt, chn = buf[0], buf[1], buf[2], buf[3], buf[4], buf[5], buf[6]
    oF, oJ, oH, xF, xJ, xH = buf[7], buf[8], buf[9], buf[10], buf[11], buf[12]
    vin = np.empty(R, np.float32)
    vex = np.empty(R, np.float32)
    ur = np.empty(R, np.int64)
    cu = np.empty(R, np.float32)
    su = np.empty(R, np.float32)
    dhi = np.empty(R, np.float32)
    best = np.empty(R, np.float32)
    hit = np.zeros(1, np.int64)
    for ch in range(chunk0, chunk1):
        for li in range(ch, L, nchunk):
            ho = half_open[li]
            n = _gather(Q, NQ, RT, HN, order, cstart, CC, CR, CX, gp[li], u[li], e1[li], e2[li], ho, fp, fmargin,
                        reach2, R == 1, cos_r[0], sin_r[0], dlim, idx, ca, cb, cna, cnb, cns, crt, chn, oF, oJ,
                        oH, xF, xJ, xH)
            _roll_minima(n, ca, cb, cna, cnb, cns, crt, chn, oF, oJ, oH, xF, xJ, xH, cos_r,
                         sin_r, hyF, hyJ, hyH, fmargin, vin, vex)
            nu = 0
            for r in range(R):
                d_hi = -_BIG
                for k in range(D):
                    d = depths[k]
                    if d < vin[r]:
                        free[li, r, k] = 1
                    elif d < vex[r] and (all_needed or need[li, r, k]):
                        d_hi = d
                if d_hi > -_BIG:
                    ur[nu] = r
                    cu[nu] = cos_r[r]
                    su[nu] = sin_r[r]
                    dhi[nu] = d_hi
                    nu += 1
            if nu > 0 and refine:
                _refine(n, idx, ca, cb, cna, cnb, cns, crt, chn, oF, oJ, oH, nu, cu, su, dhi,
                        best, M, NM, RTM, HNM, mstart, F, NF, RTF, HNF, fstart, gp[li],
                        u[li], e1[li], e2[li], ho, fp, fmargin, hit)
                for j in range(nu):
                    r = ur[j]
                    for k in range(D):
                        d = depths[k]
                        if d >= vin[r] and d < vex[r] and d < best[j]:
                            free[li, r, k] = 1
            n_refined[li] = nu


@njit(cache=True)
def probe():
    """A trivial cached function, compiled first: a cache miss here means a cold cache."""
    return 0


_B = _u1[:, :, ::1]  # (L, R, D) uint8 flags
_LINE = (_V,) * 13  # the per-line candidate arrays of _gather, in its order
# One signature per kernel, callees before callers (compiled in this order).
SIGNATURES = {
    "_gather": (_M, _M, _V, _V, _i8[::1], _i8[::1], _M, _V, _V, _V, _V, _V, _V, _f4, _M, _f4, _V, types.boolean,
                _f4, _f4, _f4, _i4[::1]) + _LINE,
    "_roll_minima": (_i8,) + _LINE + (_V, _V, _f4, _f4, _f4, _f4, _V, _V),
    "_refine": (_i8, _i4[::1]) + _LINE[:10] + (_i8, _V, _V, _V, _V, _M, _M, _V, _V, _i8[::1], _M, _M,
                                                 _V, _V, _i8[::1], _V, _V, _V, _V, _f4, _M, _f4,
                                                 _i8[::1]),
    "sweep_lines": (_M, _M, _M, _M, _V, _M, _M, _V, _V, _i8[::1], _i8[::1], _M, _V, _V, _M, _M, _V, _V,
                    _i8[::1], _M, _M, _V, _V, _i8[::1], _M, _V, _V, _V, _V, _f4, types.boolean, _B, _B,
                    _i4[::1], _i8, _i8, _i8),
    "assemble_rows": (_B, *(types.float64[:, ::1],) * 4, *(types.float64[::1],) * 3, _i8[::1], _M,
                      _f4[:, :, :, ::1], _M, _M, _M, _M, _f4[:, :, ::1], _f4[:, :, ::1], _M, _i8, _i8),
}
