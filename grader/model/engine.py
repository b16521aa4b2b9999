"""The compiled rig engine: the digital loop and the integrator, over a batch of runs.

One numba-compiled implementation (``cache=True``, no fastmath: same bytes on any CPU)
behind :func:`grader.model.rig.simulate_rig`, grading's design checks, synth and the
diagnosis fitter. Per run and per sample instant t_k = k·T::

    ADC: y_k = x_k + noise_k, rounded to the ADC's step when quantised
    controller: e_k = k_fb·(r_k − y_k); u_k = Kp·e_k + Ki·T·Σe + Kd·(e_k − e_{k−1})/T, clipped to ±10 V (DAC)
    (a replayed run: u_k = noise_k, the controller output a rig recorded [V], and y_k = x_k)
    hold: u held over [t_k, t_k+1), delayed by lag whole samples and a fractional phase
    amplifier: i = clip(Kamp·u, ±i_lim) -> backlash (valve_hysteresis) -> plant

The plant (:mod:`grader.model.hydraulic`) is advanced over each piece of the hold interval
(two pieces where a fractional delay switches the held output). Where it is linear between
events, a piece is one exact zero-order-hold step z ← Φ·z + Γ·w (Φ, Γ from the matrix
exponential, computed once per run); otherwise it is ``m`` classical RK4 substeps. An event
(a slipping mass stopping, a stuck one breaking away) found at the end of a step is located
inside it by Illinois regula falsi on the exact flow (a Taylor series of the linear flow, or
RK4 over the partial step), the mode switched there, and the rest of the step integrated in
the new mode.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from grader.model import hydraulic as plant
from grader.model.rig_setup import DAC_LIMIT, RigArrays

Array = NDArray[np.float64]
NS, NI = plant.N_STATES, plant.N_INPUTS
# controller / actuator / sensor row
T_, KP, KI_T, KD_T, K_FB, KAMP, I_LIM, HALF_HYST, LSB, CPI, LAG, PHASE, REPLAY = range(13)
N_CTL = 13
TAYLOR_TERMS = 16  # for a balanced norm <= 0.5: truncation below 1e-17
MAX_EVENTS = 16  # per substep; beyond, friction just opposes the velocity (chatter)
EVENT_ITERATIONS = 60


def pack_controls(a: RigArrays, replay: NDArray[np.bool_] | None = None) -> Array:
    """Per-run controller, actuator and sensor rows (n, N_CTL); ``replay`` marks the runs driven by a recorded
    controller output instead of the controller."""
    lag = np.floor(a.delay / a.T + 1e-9)
    phase = a.delay - lag * a.T
    phase[phase < 1e-9 * a.T] = 0.0
    lsb = np.where(a.lsb > 0, 1.0, 0.0)
    cols = (np.full(a.n, a.T), a.Kp, a.Ki_T, a.Kd_T, a.k_fb, a.Kamp, a.i_lim, a.half_hyst, lsb, a.counts_per_in,
            lag, phase, np.zeros(a.n) if replay is None else np.asarray(replay, dtype=np.float64))
    return np.ascontiguousarray(np.stack(cols, axis=1), dtype=np.float64)


@njit(cache=True)
def _balanced_norm(m) -> float:  # noqa: ANN001
    """1-norm of D⁻¹·m·D after Osborne balancing with powers of two (states in mixed units)."""
    b = m.copy()
    n = b.shape[0]
    for _ in range(40):
        done = True
        for i in range(n):
            c = r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(b[j, i])
                    r += abs(b[i, j])
            if c == 0.0 or r == 0.0:
                continue
            f, s = 1.0, c + r
            while c < r / 2.0:
                c, r, f = c * 2.0, r / 2.0, f * 2.0
            while c >= r * 2.0:
                c, r, f = c / 2.0, r * 2.0, f / 2.0
            if c + r < 0.95 * s:
                done = False
                b[:, i] *= f
                b[i, :] /= f
        if done:
            break
    best = 0.0
    for j in range(n):
        col = 0.0
        for i in range(n):
            col += abs(b[i, j])
        best = max(best, col)
    return best


@njit(cache=True)
def _halvings(norm: float, tau: float) -> int:
    x = norm * tau / 0.5
    return max(0, int(math.ceil(math.log2(x)))) if x > 1.0 else 0


@njit(cache=True)
def _matmul(a, b, out):  # noqa: ANN001, ANN201
    n, k, m = a.shape[0], a.shape[1], b.shape[1]
    for i in range(n):
        for j in range(m):
            s = 0.0
            for q in range(k):
                s += a[i, q] * b[q, j]
            out[i, j] = s


@njit(cache=True)
def _zoh(Ac, Bc, norm, h, phi, gam):  # noqa: ANN001, ANN201, N803
    """Φ = e^{Ac·h}, Γ = ∫e^{Ac·s}ds·Bc: Taylor series of the augmented matrix, scaling and squaring."""
    n = NS + NI
    s = _halvings(norm, h)
    a = np.zeros((n, n))
    scale = h / 2.0**s
    a[:NS, :NS] = Ac * scale
    a[:NS, NS:] = Bc * scale
    out, term, tmp = np.eye(n), np.eye(n), np.empty((n, n))
    for k in range(1, TAYLOR_TERMS + 1):
        _matmul(term, a, tmp)
        term[:, :] = tmp / k
        out += term
    for _ in range(s):
        _matmul(out, out, tmp)
        out[:, :] = tmp
    phi[:, :] = out[:NS, :NS]
    gam[:, :] = out[:NS, NS:]


@njit(cache=True)
def _mv(m, z, out):  # noqa: ANN001, ANN201
    for i in range(m.shape[0]):
        s = 0.0
        for j in range(m.shape[1]):
            s += m[i, j] * z[j]
        out[i] = s


# scratch rows of the per-run work array
TERM, NXT, BW, K1, K2, K3, K4, TMP, ZT, W_ = range(10)
N_WORK = 10


@njit(cache=True)
def _taylor_flow(z, tau, Ac, Bc, norm, w, out, wk):  # noqa: ANN001, ANN201, N803
    """Exact linear flow of dz/dt = Ac·z + Bc·w over ``tau`` into ``out`` (pieces of balanced norm <= 0.5)."""
    pieces = 2 ** _halvings(norm, tau)
    h = tau / pieces
    term, nxt, bw = wk[TERM], wk[NXT], wk[BW]
    _mv(Bc, w, bw)
    out[:] = z
    for _ in range(pieces):
        _mv(Ac, out, term)
        for r in range(NS):
            term[r] = (term[r] + bw[r]) * h
            out[r] += term[r]
        for k in range(2, TAYLOR_TERMS + 1):
            _mv(Ac, term, nxt)
            small = True
            for r in range(NS):
                term[r] = nxt[r] * (h / k)
                out[r] += term[r]
                small = small and abs(term[r]) <= 1e-17 * abs(out[r])
            if small:
                break


@njit(cache=True)
def _rk4_flow(z, tau, par, i, mode, hmax, out, wk):  # noqa: ANN001, ANN201
    """RK4 over ``tau`` in equal steps of at most ``hmax``, into ``out``."""
    n = max(1, int(math.ceil(tau / hmax * (1.0 - 1e-12))))
    h = tau / n
    k1, k2, k3, k4, tmp = wk[K1], wk[K2], wk[K3], wk[K4], wk[TMP]
    out[:] = z
    for _ in range(n):
        plant.rhs(out, par, i, mode, k1)
        for r in range(NS):
            tmp[r] = out[r] + (0.5 * h) * k1[r]
        plant.rhs(tmp, par, i, mode, k2)
        for r in range(NS):
            tmp[r] = out[r] + (0.5 * h) * k2[r]
        plant.rhs(tmp, par, i, mode, k3)
        for r in range(NS):
            tmp[r] = out[r] + h * k3[r]
        plant.rhs(tmp, par, i, mode, k4)
        for r in range(NS):
            out[r] = out[r] + (h / 6.0) * (k1[r] + 2.0 * (k2[r] + k3[r]) + k4[r])


@njit(cache=True)
def _flow(z, tau, mode, i, par, lin, mats, hmax, out, wk):  # noqa: ANN001, ANN201
    """The plant's state after ``tau`` [s] in ``mode`` with current ``i`` held, into ``out``."""
    if not lin:
        _rk4_flow(z, tau, par, i, mode, hmax, out, wk)
        return
    Acs, Bcs, norms = mats[0], mats[1], mats[2]  # noqa: N806
    kind = 0 if mode != 0 else 1
    w = wk[W_, :NI]
    plant.linear_input(par, i, mode, w)
    _taylor_flow(z, tau, Acs[kind], Bcs[kind], norms[kind], w, out, wk)


@njit(cache=True)
def _locate(z, rem, glo, ghi, mode, i, par, lin, mats, hmax, wk) -> float:  # noqa: ANN001
    """Time in (0, rem] where the event value turns negative: Illinois regula falsi (bisection from 0)."""
    lo, hi, side = 0.0, rem, 0
    zt = wk[ZT]
    for _ in range(EVENT_ITERATIONS):
        tau = lo + glo * (hi - lo) / (glo - ghi) if glo > 0.0 else 0.5 * (lo + hi)
        if not lo < tau < hi:
            tau = 0.5 * (lo + hi)
        _flow(z, tau, mode, i, par, lin, mats, hmax, zt, wk)
        g = plant.event_value(zt, par, mode)
        if g == 0.0:
            return tau
        if g < 0.0:
            hi, ghi = tau, g
            if side == -1:
                glo *= 0.5
            side = -1
        else:
            lo, glo = tau, g
            if side == 1:
                ghi *= 0.5
            side = 1
        if hi - lo <= 1e-12 * rem:
            break
    return hi


@njit(cache=True, inline="always")
def _std_step(z, mode, i, std, hs, par, lin, phis, gams, w, out, wk):  # noqa: ANN001, ANN201
    """The plant over one standard substep hs[std] in ``mode``, into ``out``."""
    if not lin:
        _rk4_flow(z, hs[std], par, i, mode, hs[std], out, wk)
        return
    kind = 0 if mode != 0 else 1
    plant.linear_input(par, i, mode, w)
    for r in range(NS):
        s = 0.0
        for c in range(NS):
            s += phis[kind, std, r, c] * z[c]
        for c in range(NI):
            s += gams[kind, std, r, c] * w[c]
        out[r] = s


@njit(cache=True, inline="always")
def _substep(z, mode, i, std, hs, par, lin, ev, mats, phis, gams, w, z1, wk):  # noqa: ANN001, ANN201
    """One substep of standard length hs[std], events located inside; updates ``z``, returns the mode."""
    _std_step(z, mode, i, std, hs, par, lin, phis, gams, w, z1, wk)
    if ev and plant.event_value(z1, par, mode) < 0.0:
        mode = _events(z, mode, i, hs[std], par, lin, mats, z1, wk)
    for r in range(NS):
        z[r] = z1[r]
    return mode


@njit(cache=True)
def _events(z, mode, i, h, par, lin, mats, z1, wk):  # noqa: ANN001, ANN201
    """The substep of length h from ``z`` ended past an event (state ``z1``): locate it, switch the mode
    there and finish the substep; ``z1`` gets the end state. Returns the mode."""
    rem, n_ev = h, 0
    while plant.event_value(z1, par, mode) < 0.0 and n_ev < MAX_EVENTS:
        g0 = plant.event_value(z, par, mode)
        tau = 0.0 if g0 < 0.0 else _locate(z, rem, g0, plant.event_value(z1, par, mode), mode, i, par, lin, mats,
                                           h, wk)
        if tau > 0.0:
            _flow(z, tau, mode, i, par, lin, mats, h, z1, wk)
            z[:] = z1
        mode = plant.after_event(z, par, mode)
        rem -= tau
        n_ev += 1
        if rem <= 1e-12 * h:
            z1[:] = z
            return mode
        _flow(z, rem, mode, i, par, lin, mats, h, z1, wk)
    return mode


@njit(cache=True)
def _pieces(ctl, m: int, exact_whole: bool):  # noqa: ANN001, ANN201
    """(substeps before the delayed switch, after it, their lengths [s]) of one hold interval."""
    T, phase = ctl[T_], ctl[PHASE]
    hs = np.zeros(2)
    if exact_whole:
        n_a = 1 if phase > 0.0 else 0
        n_b = 1
    elif phase > 0.0:
        n_a = int(min(max(np.rint(phase / T * (m + 1)), 1.0), m))
        n_b = m + 1 - n_a
    else:
        n_a, n_b = 0, m
    if n_a > 0:
        hs[0] = phase / n_a
    hs[1] = (T - phase) / n_b
    return n_a, n_b, hs


@njit(cache=True)
def _matrices(par, ev: bool, hs):  # noqa: ANN001, ANN201
    """Continuous (Ac, Bc, balanced norm) per kind (0 slipping, 1 stuck) and ZOH maps per standard length."""
    Acs, Bcs, norms = np.zeros((2, NS, NS)), np.zeros((2, NS, NI)), np.zeros(2)
    phis, gams = np.zeros((2, 2, NS, NS)), np.zeros((2, 2, NS, NI))
    for kind in range(2 if ev else 1):
        plant.linear_system(par, 1 if kind == 0 else 0, Acs[kind], Bcs[kind])
        norms[kind] = _balanced_norm(Acs[kind])
        for std in range(2):
            if hs[std] > 0.0:
                _zoh(Acs[kind], Bcs[kind], norms[kind], hs[std], phis[kind, std], gams[kind, std])
    return (Acs, Bcs, norms), phis, gams


@njit(cache=True, inline="always")
def _valve(ctl, u: float, back: float):  # noqa: ANN001, ANN201
    """Amplifier (gain, ±i_lim) and backlash: (current [mA], new backlash state)."""
    i = min(max(ctl[KAMP] * u, -ctl[I_LIM]), ctl[I_LIM])
    if ctl[HALF_HYST] > 0.0:
        back = min(max(back, i - ctl[HALF_HYST]), i + ctl[HALF_HYST])
        return back, back
    return i, back


@njit(cache=True, inline="always", _nrt=False)
def _loop(par, ctl, r, noise, K, lin, ev, n_a, n_b, hs, mats, phis, gams, Y, U, X, z, z1, w, wk):  # noqa: ANN001, ANN201, N803
    """The digital loop over K samples (inlined per (lin, ev) so that each path compiles tight)."""
    lag = int(ctl[LAG])
    z[0] = r[0]
    mode = plant.initial_mode(par)
    integ = e_prev = back = 0.0
    replay = ctl[REPLAY] > 0.0
    for k in range(K):
        x = z[0]
        if replay:  # the recorded controller output drives the plant
            y, u = x, min(max(noise[k], -DAC_LIMIT), DAC_LIMIT)
        else:
            y = x + noise[k]
            if ctl[LSB] > 0.0:
                y = np.rint(y * ctl[CPI]) / ctl[CPI]
            e = ctl[K_FB] * (r[k] - y)
            integ += e
            u = min(max(ctl[KP] * e + ctl[KI_T] * integ + ctl[KD_T] * (e - e_prev), -DAC_LIMIT), DAC_LIMIT)
            e_prev = e
        Y[k], U[k], X[k] = y, u, x
        for piece in range(2):
            n = n_a if piece == 0 else n_b
            if n == 0:
                continue
            j = k - lag - 1 + piece
            i, back = _valve(ctl, U[j] if j >= 0 else 0.0, back)
            for _ in range(n):
                mode = _substep(z, mode, i, piece, hs, par, lin, ev, mats, phis, gams, w, z1, wk)


@njit(cache=True)
def _run(par, ctl, r, noise, K: int, m: int, Y, U, X):  # noqa: ANN001, ANN201, N803
    """One run over K samples into the rows Y (y [in]), U (u [V]), X (x [in])."""
    lin, ev = plant.is_linear(par), plant.has_events(par)
    n_a, n_b, hs = _pieces(ctl, m, lin)
    mats, phis, gams = _matrices(par, ev, hs) if lin else _matrices(par, False, np.zeros(2))
    z, z1, w, wk = np.zeros(NS), np.zeros(NS), np.zeros(NI), np.zeros((N_WORK, NS))
    if lin and not ev:
        _loop(par, ctl, r, noise, K, True, False, n_a, n_b, hs, mats, phis, gams, Y, U, X, z, z1, w, wk)
    elif lin:
        _loop(par, ctl, r, noise, K, True, True, n_a, n_b, hs, mats, phis, gams, Y, U, X, z, z1, w, wk)
    else:
        _loop(par, ctl, r, noise, K, False, ev, n_a, n_b, hs, mats, phis, gams, Y, U, X, z, z1, w, wk)


@njit(cache=True, nogil=True)
def _run_batch(par, ctl, r, noise, K, m, Y, U, X):  # noqa: ANN001, ANN201, N803
    """Every run of the batch; without the GIL, so a second thread can simulate another batch meanwhile."""
    for j in range(par.shape[0]):
        _run(par[j], ctl[j], r[j], noise[j], K[j], m[j], Y[j], U[j], X[j])


def stepped(a: RigArrays) -> NDArray[np.bool_]:
    """Runs whose cost grows with their fastest mode, by the plant's own predicates: RK4 substeps where it is not
    linear between events, or events to locate; a linear run without events is one exact step per sample. The
    predicates are called as Python: numba's ``py_func``, or the function itself where ``NUMBA_DISABLE_JIT`` left it
    plain."""
    is_linear, has_events = (getattr(f, "py_func", f) for f in (plant.is_linear, plant.has_events))
    return np.array([not is_linear(p) or has_events(p) for p in plant.pack(a)], dtype=bool)


def run(a: RigArrays, r: Array, noise: Array, K: NDArray[np.int64], m: NDArray[np.int64],
        replay: NDArray[np.bool_] | None = None) -> tuple[Array, Array, Array]:
    """(Y, U, X), each (n, Kmax): measured y [in], u [V] and true x [in] of each run for commands
    ``r`` (n, Kmax) [in] and reading noise (n, Kmax) [in]; run j uses its first K[j] samples and
    m[j] RK4 substeps per sample where the plant is not linear between events. A run marked in ``replay`` is
    driven by ``noise`` as its controller output [V] (recorded on a rig) instead of its controller."""
    n, k_max = r.shape
    Y, U, X = np.zeros((n, k_max)), np.zeros((n, k_max)), np.zeros((n, k_max))
    _run_batch(plant.pack(a), pack_controls(a, replay), np.ascontiguousarray(r, dtype=np.float64),
               np.ascontiguousarray(noise, dtype=np.float64), np.asarray(K, dtype=np.int64),
               np.asarray(m, dtype=np.int64), Y, U, X)
    return Y, U, X
