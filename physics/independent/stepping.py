"""Nonlinear time stepping of the line-of-action DOF (numba), the check on the LTI solve.

``m ẍ + c (ẋ − ẋ_s) + Σ_j k_j max(x + e_ecc − e_j, 0) + k_sh (x − x̄) = F(t) + f_fr(t)``
with the per-sample springs of :func:`physics.independent.generator.solve_static_mesh`:
the stiffness varies with time (parametric excitation) and a pair can lose contact
dynamically, which the frequency-domain model (linear about the mean loaded stiffness) cannot.
Newmark average acceleration (unconditionally stable); each step's equation is monotone and
piecewise linear in x, so it is solved exactly by sorting the springs' breakpoints (no
iteration, no contact-set guess).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@njit(cache=True)
def _step_chunk(  # pragma: no cover - compiled
    state: FloatArray,
    ks: FloatArray,
    es: FloatArray,
    ecc: FloatArray,
    xs_rate: FloatArray,
    force: FloatArray,
    h: float,
    mass: float,
    damping: float,
    k_shaft: float,
    x_ref: float,
    out_force: FloatArray,
    out_x: FloatArray,
) -> int:
    """Advance ``state = [x, v, a]`` over the chunk's samples; returns samples out of contact."""
    n, nj = ks.shape
    x0, v0, a0 = state[0], state[1], state[2]
    lin = 4.0 * mass / (h * h) + 2.0 * damping / h + k_shaft
    bk = np.empty(nj)
    bb = np.empty(nj)
    separated = 0
    for i in range(n):
        # Breakpoints b_j = e_j − e_ecc of the springs in contact, insertion-sorted.
        m = 0
        for j in range(nj):
            kj = ks[i, j]
            if kj <= 0.0:
                continue
            b = es[i, j] - ecc[i]
            p = m
            while p > 0 and bb[p - 1] > b:
                bb[p] = bb[p - 1]
                bk[p] = bk[p - 1]
                p -= 1
            bb[p] = b
            bk[p] = kj
            m += 1
        rhs = (
            force[i]
            + k_shaft * x_ref
            + mass * (4.0 / (h * h) * x0 + 4.0 / h * v0 + a0)
            + damping * (2.0 / h * x0 + v0 + xs_rate[i])
        )
        ksum = lin
        ksb = 0.0
        x1 = rhs / ksum
        active = 0
        while active < m and x1 > bb[active]:
            ksb += bk[active] * bb[active]
            ksum += bk[active]
            active += 1
            x1 = (rhs + ksb) / ksum
        if active == 0:
            separated += 1
        v1 = 2.0 / h * (x1 - x0) - v0
        a1 = 4.0 / (h * h) * (x1 - x0) - 4.0 / h * v0 - a0
        elastic = 0.0
        for p in range(active):
            elastic += bk[p] * (x1 - bb[p])
        out_force[i] = elastic + damping * (v1 - xs_rate[i])
        out_x[i] = x1
        x0, v0, a0 = x1, v1, a1
    state[0], state[1], state[2] = x0, v0, a0
    return separated


class NonlinearStepper:
    """Chunk consumer for :func:`solve_static_mesh`: integrates as the springs are built.

    Start at the static solution of the first sample with zero velocity; the record's padding
    absorbs the start transient.
    """

    def __init__(
        self, n: int, h: float, mass: float, damping: float, k_shaft: float, x_ref: float
    ) -> None:
        self.h, self.mass, self.damping = h, mass, damping
        self.k_shaft, self.x_ref = k_shaft, x_ref
        self.mesh_force = np.empty(n)
        self.x = np.empty(n)
        self.state = np.zeros(3)
        self.previous_xs: float | None = None
        self.separated_samples = 0

    def __call__(
        self, lo: int, hi: int, ks: FloatArray, es: FloatArray, ecc: FloatArray,
        xs: FloatArray, force: FloatArray, friction_line: FloatArray,
    ) -> None:
        if self.previous_xs is None:
            self.state[0] = xs[0]
            self.previous_xs = float(xs[0])
        rate = np.diff(np.concatenate([[self.previous_xs], xs])) / self.h
        self.previous_xs = float(xs[-1])
        self.separated_samples += int(
            _step_chunk(
                self.state,
                np.ascontiguousarray(ks),
                np.ascontiguousarray(es),
                np.ascontiguousarray(ecc),
                rate,
                np.ascontiguousarray(force + friction_line),
                self.h,
                self.mass,
                self.damping,
                self.k_shaft,
                self.x_ref,
                self.mesh_force[lo:hi],
                self.x[lo:hi],
            )
        )
