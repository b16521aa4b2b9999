"""Least squares for many fits at once, batched so each round is one simulator pass.

A fit is a candidate on a set of runs (all of them, or the training runs of a
cross-validation fold). Its objective at θ is Σ NRMSE_run² over its runs: the residual
vector ``(y_model − y)/(scale·√n)`` stacked over those runs. Every round evaluates, for
every fit still improving, the Levenberg–Marquardt trial steps (one per damping factor) in
one batched call and keeps the best if it lowers the cost; then, in a second, the
forward-difference Jacobian at each accepted step only (a Jacobian per trial would cost three
times as many simulations for the same path). Starting points of the all-runs fits come from a profile: the
linear parameters fitted at each magnitude of a coarse grid over the effect's realistic range.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from grader.gap.backend import Point, stretches
from grader.gap.candidates import Candidate
from grader.gap.lm import damped_steps, sumsq
from grader.gap.objective import RunObjective
from grader.model.params import RigParams

Array = NDArray[np.float64]
#: (requests of (point, run index)) -> y per request
Requests = Callable[[Sequence[tuple[Point, int]]], list[Array]]
#: ln(Kce/Kce₀) tried before fitting: an unmodelled effect can bias the students' Kce threefold either way.
KCE_LINE = (-1.2, -0.6, 0.0, 0.5, 1.0)
#: Relative cost decrease below which a fit counts as converged.
CONVERGED = 1e-4
#: Cap on a normalised residual: a diverging trial model gets a large, finite cost.
RES_CAP = 1e3
#: Most samples simulated in one pass: the positions of a pass are all held until its residuals are taken. Every
#: pass of a lab's runs (a few seconds each) fits in one; five 30 s runs need several.
MAX_PASS_SAMPLES = 8_000_000


@dataclass(frozen=True)
class FitState:
    """A candidate fitted on ``runs`` at θ: stacked residual ``res``, Jacobian ``jac`` (rows × θ), damping ``lam``."""

    candidate: Candidate
    runs: tuple[int, ...]
    theta: Array
    res: Array
    jac: Array | None = None
    lam: float = 1e-2
    done: bool = False
    n_free: int | None = None  # only the first n_free coordinates of θ move (None: all)

    @property
    def cost(self) -> float:
        return sumsq(self.res)

    @property
    def free(self) -> int:
        return self.candidate.n_theta if self.n_free is None else self.n_free


def _probe(c: Candidate, theta: Array, n_free: int, hi: Array) -> list[Array]:
    """θ moved by one forward (or, at the upper bound ``hi``, backward) step in each free coordinate."""
    out = []
    for j, h in enumerate(c.steps()[:n_free]):
        t = theta.copy()
        t[j] = t[j] + h if t[j] + h <= hi[j] else t[j] - h
        out.append(t)
    return out


def _jacobian(c: Candidate, theta: Array, base: Array, probes: Sequence[Array], hi: Array) -> Array:
    """Columns for the free coordinates (as many as ``probes``), probed as :func:`_probe` with ``hi``."""
    cols = [(r - base) / (h if theta[j] + h <= hi[j] else -h) for j, (h, r) in enumerate(zip(c.steps(), probes))]
    return np.stack(cols, axis=1)


class BatchFitter:
    """Fits many (candidate, runs) problems around one baseline with a shared simulator; each run is
    compared through its objective (:mod:`grader.gap.objective`)."""

    def __init__(self, objectives: Sequence[RunObjective], base: RigParams, simulate: Requests) -> None:
        self.objectives, self.base, self.sim = list(objectives), base, simulate
        self.runs = [o.run for o in self.objectives]

    @property
    def lengths(self) -> list[int]:
        """Residual entries per run."""
        return [o.length for o in self.objectives]

    def residuals(self, jobs: Sequence[tuple[Candidate, Array, tuple[int, ...]]]) -> list[Array]:
        """Stacked residual of each (candidate, θ, runs) job."""
        out: list[Array] = []
        sizes = [sum(self.runs[i].n for i in idx) for _, _, idx in jobs]
        for group in stretches(sizes, MAX_PASS_SAMPLES, padded=False):
            requests = [(pt, i) for c, th, idx in jobs[group] for pt in [c.point(self.base, th)] for i in idx]
            ys = iter(self.sim(requests))
            for _, _, idx in jobs[group]:
                parts = [self.objectives[i].residual(next(ys)) for i in idx]
                out.append(np.clip(np.nan_to_num(np.concatenate(parts), nan=RES_CAP), -RES_CAP, RES_CAP))
        return out

    def line(self, grid: Sequence[tuple[Candidate, Array]], *, offsets: Sequence[float] = KCE_LINE,
             whole: bool = False) -> list[FitState]:
        """Each (candidate, θ) with ln Kce moved by the best of ``offsets`` (one batched evaluation on this fitter's
        runs), as a state whose linear coordinates (and fitted null) will move, or with ``whole`` all of θ."""
        every = tuple(range(len(self.runs)))
        jobs = [(c, th + np.array([0.0, dk] + [0.0] * (th.size - 2)), every) for c, th in grid for dk in offsets]
        res = self.residuals(jobs)
        out = []
        for k in range(len(grid)):
            j = min(range(len(offsets)), key=lambda i: sumsq(res[k * len(offsets) + i]))
            c, th, _ = jobs[k * len(offsets) + j]
            out.append(FitState(c, every, th, res[k * len(offsets) + j], n_free=None if whole else c.lead))
        return out

    def profile(self, starts: Sequence[tuple[Candidate, Array]], owner: Sequence[int], *, rounds: int) -> list[FitState]:
        """The linear parameters fitted at each start (its magnitudes held; Kce from the best of a coarse
        line first); the best start of each owner is returned, ready to fit all coordinates."""
        states = self.refine(self.line(list(starts)), rounds=rounds, dampings=(1.0,), final_jacobian=False)
        best: dict[int, FitState] = {}
        for s, k in zip(states, owner):
            if k not in best or s.cost < best[k].cost:
                best[k] = s
        return [replace(best[k], n_free=None, jac=None, done=False) for k in sorted(best)]


    def rebase(self, states: Sequence[FitState]) -> list[FitState]:
        """The same θ evaluated on this fitter's runs: residual and Jacobian in one round."""
        every = tuple(range(len(self.runs)))
        jobs = [(s.candidate, t, every) for s in states
                for t in [s.theta, *_probe(s.candidate, s.theta, s.free, self._top(s))]]
        res, out, pos = self.residuals(jobs), [], 0
        for s in states:
            n = s.free
            jac = _jacobian(s.candidate, s.theta, res[pos], res[pos + 1:pos + 1 + n], self._top(s))
            out.append(replace(s, runs=every, res=res[pos], jac=jac, done=False))
            pos += n + 1
        return out

    def _top(self, s: FitState) -> Array:
        """Upper bounds of ``s``'s θ around this fitter's baseline."""
        return s.candidate.bounds(self.base)[1]

    def _trials(self, s: FitState, dampings: Sequence[float]) -> list[tuple[float, Array]]:
        """(λ, θ) of the damped Gauss–Newton steps from ``s``, kept within the bounds."""
        assert s.jac is not None
        lo, hi = s.candidate.bounds(self.base)
        lams = s.lam * np.asarray(dampings, dtype=float)
        steps = damped_steps(np.ascontiguousarray(s.jac), s.res, lams)
        out = []
        for lam, d in zip(lams, steps):
            step = np.zeros_like(s.theta)
            step[:s.free] = d
            out.append((float(lam), np.clip(s.theta + step, lo, hi)))
        return out

    def _jacobians(self, states: list[FitState], which: Sequence[int], *, halve_damping: bool = False) -> None:
        """Fill in the Jacobian of ``states[k]`` at its θ for each k of ``which`` (one batched evaluation);
        ``halve_damping`` also halves λ, as an accepted step does."""
        jobs = [(states[k].candidate, t, states[k].runs) for k in which
                for t in _probe(states[k].candidate, states[k].theta, states[k].free, self._top(states[k]))]
        res, pos = self.residuals(jobs), 0
        for k in which:
            s = states[k]
            lam = max(s.lam * 0.5, 1e-6) if halve_damping else s.lam
            jac = _jacobian(s.candidate, s.theta, s.res, res[pos:pos + s.free], self._top(s))
            states[k] = replace(s, jac=jac, lam=lam)
            pos += s.free

    def round(self, states: Sequence[FitState], dampings: Sequence[float], *, jacobian: bool = True) -> list[FitState]:
        """One Levenberg–Marquardt round for every state not done (each needs its Jacobian): the trial
        steps in one batched evaluation, the best kept if it lowers the cost; then, with ``jacobian``,
        the Jacobians at the accepted steps (else those states carry ``jac=None``)."""
        jobs: list[tuple[Candidate, Array, tuple[int, ...]]] = []
        plan: list[tuple[int, float, Array]] = []
        for k, s in enumerate(states):
            if not s.done:
                for lam, th in self._trials(s, dampings):
                    plan.append((k, lam, th))
                    jobs.append((s.candidate, th, s.runs))
        new = list(states)
        best: dict[int, FitState] = {}
        for (k, lam, th), res in zip(plan, self.residuals(jobs)):
            cand = replace(states[k], theta=th, res=res, jac=None, lam=max(lam * 0.5, 1e-6))
            if k not in best or cand.cost < best[k].cost:
                best[k] = cand
        moved = []
        for k, cand in best.items():
            s = states[k]
            if cand.cost < s.cost:
                new[k] = replace(cand, done=(s.cost - cand.cost) < CONVERGED * s.cost)
                moved.append(k)
            else:
                new[k] = replace(s, lam=s.lam * 16.0, done=s.lam > 1e4)
        if jacobian:
            self._jacobians(new, moved)
        return new

    def refine(self, states: Sequence[FitState], *, rounds: int, dampings: Sequence[float],
               final_jacobian: bool = True) -> list[FitState]:
        """Up to ``rounds`` rounds (Jacobians first where missing). With ``final_jacobian`` every Jacobian
        ends at the final θ; without, a state whose last step moved it carries ``jac=None`` (for callers
        that keep only θ and the residual)."""
        out = list(states)
        self._jacobians(out, [k for k, s in enumerate(out) if s.jac is None], halve_damping=True)
        for r in range(rounds):
            if all(s.done for s in out):
                break
            out = self.round(out, dampings, jacobian=final_jacobian or r < rounds - 1)
        return out

    def fit(self, states: Sequence[FitState], *, rounds: int, final_jacobian: bool = True) -> list[FitState]:
        """All coordinates: Levenberg–Marquardt with three dampings per round (see :meth:`refine`)."""
        return self.refine(states, rounds=rounds, dampings=(0.25, 1.0, 4.0), final_jacobian=final_jacobian)


def grid_starts(candidates: Sequence[Candidate], theta0: Sequence[Array] | None = None
                ) -> tuple[list[tuple[Candidate, Array]], list[int]]:
    """Starts over the grid of the magnitude of each candidate's last added effect, from ``theta0[k]``
    (default: the baseline and zero magnitudes); with the index of the candidate each belongs to."""
    starts: list[tuple[Candidate, Array]] = []
    owner: list[int] = []
    for k, c in enumerate(candidates):
        base = np.zeros(c.n_theta) if theta0 is None else np.asarray(theta0[k], dtype=float)
        last = c.params[-1] if c.params and c.params[-1].effect == c.names[-1] else None
        for m in ([None] if last is None else last.grid()):
            th = base.copy()
            if m is not None:
                th[-1] = m
            starts.append((c, th))
            owner.append(k)
    return starts, owner
