"""Compiled time-integration loop of the gear-pair model (numba).

Newmark average acceleration (β = 1/4, γ = 1/2, unconditionally stable) on the equations

    M ẍ + C ẋ + K x + Σ_lines ∫ k(z) H(δ) [δ + η δ̇] V(z) dz = F(t),
    δ(z) = V(z)·x + g(z, t),        V(z) = V0 + z V1,

where the integral runs over the contact lines on the base plane (z across the face),
``g`` collects eccentricity and the normal deviations (tip relief, pitch errors, spalls)
and H is the unit step: a part of a line whose deviation exceeds the local approach
carries no load (contact loss, not linearised away; ``p[P_LINEAR_MESH]`` = 1 sets H ≡ 1
over the geometric contact zone: the linearised mesh of many simulators, tension allowed).
Because V is affine in z, the mesh stiffness matrix is U S Uᵀ with U = [V0 V1] and a 2×2 S,
and each step solves with the constant ``A⁻¹`` (A = 4M/h² + 2C/h + K) plus a rank-2 Woodbury correction. The contact set
is found by iterating until it no longer changes; contact intervals on a line are exact
(δ is linear in z), and pair entry/exit and spall edges are averaged over the step's
travel so that events are not quantised to the step.

Sliding friction (Coulomb, μ·s·N per contact line across the line of action, s the sign of
the sliding velocity, which reverses at the pitch point) enters F(t) explicitly from the
normal loads at the Newmark predictor; a stiffness-per-length profile along the path of
contact scales each line's k; an anisotropic support is a full 2×2 radial block in K and C.
The motor's speed reference may fluctuate in time (Hz) or, with ``p[P_FLUCT_ORDER]`` = n ≥ 1,
at n × the pinion-shaft order, phase-locked to the pinion angle.

This is an internal module: :mod:`physics.simulator` assembles the arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.core.cpu import CPUTargetOptions

# Indices into the float parameter vector.
P_RB1, P_RB2, P_PB, P_U0, P_START, P_END, P_KLEN, P_ETA, P_HALF_FACE = range(9)
P_CA1, P_LA1, P_CA2, P_LA2, P_RELIEF_EXP = range(9, 14)
P_ECC1, P_PHI1, P_ECC2, P_PHI2 = range(14, 18)
P_KB1, P_CB1, P_KB2, P_CB2 = range(18, 22)
P_TORQUE_FF, P_LOAD, P_LOAD_FLUCT, P_LOAD_ORDER, P_LOAD_PHASE = range(22, 27)
P_SPEED, P_DRIFT, P_FLUCT, P_FLUCT_HZ, P_CONTROL_GAIN, P_TACH_PPR = range(27, 33)
P_TACH_OFFSET = 33
# Extensions (issue 6): sliding friction, stiffness profile, anisotropic supports.
P_MU, P_PITCH_POINT, P_T1T2, P_KPROFILE, P_KPROFILE_A = range(34, 39)
P_KXY1, P_CXY1, P_KYY1, P_CYY1, P_KXY2, P_CXY2, P_KYY2, P_CYY2 = range(39, 47)
# Speed fluctuation locked to a pinion-shaft order (0: the Hz-based one); linearised mesh
# (1: no contact loss, tension allowed; 0: Heaviside contact as always).
P_FLUCT_ORDER, P_FLUCT_PHASE, P_LINEAR_MESH = range(47, 50)
N_PARAMS = 50

# Values of p[P_KPROFILE].
KPROFILE_CONSTANT, KPROFILE_LINEAR, KPROFILE_PARABOLIC = range(3)

# Rows of the per-output-sample array.
OUT_PINION_ANGLE, OUT_GEAR_ANGLE, OUT_TE, OUT_MESH_FORCE = range(4)
OUT_BEARING_PINION, OUT_BEARING_GEAR, OUT_CONTACT_LENGTH = range(4, 7)
OUT_BEARING_PINION_OFF, OUT_BEARING_GEAR_OFF, OUT_FRICTION_FORCE = range(7, 10)
N_OUT = 10

# Indices into the integer DOF map (−1: locked or absent).
D_MOTOR, D_PINION_ROT, D_GEAR_ROT, D_LOAD, D_PINION_X, D_GEAR_X = range(6)
D_PINION_Y, D_GEAR_Y, D_PINION_RX, D_GEAR_RX = range(6, 10)
N_DOF_MAP = 10

MAX_PAIRS = 6

# Rows of the contact-line pieces array: face interval, gap, stiffness per length, entry
# weight, the pair's contact position and sliding sign (one array: fewer call arguments).
S_Z0, S_Z1, S_GAP, S_K, S_W, S_U, S_SLIDE = range(7)
N_SEG_ROWS = 7

# The helpers that ``integrate`` calls every step with arrays (``_relief``, ``_build_segments``,
# ``_contact_sums``, ``_friction_sums``) allocate nothing and are compiled without numba's
# reference-counting runtime (``_nrt=False``): with it, each call incremented and decremented
# every array argument's count with atomic instructions, about half the integration time.
# Same arithmetic, bit-identical records (checked on spalls, cracks, friction, linear mesh).
# ``_nrt`` is a private numba option (there since 2015, numba/numba#2350): a numba without it
# gets the plain decorator, slower and otherwise the same, instead of a KeyError at first call.
_NO_REFCOUNT = {"_nrt": False} if hasattr(CPUTargetOptions, "_nrt") else {}
_step_helper = njit(cache=True, fastmath=True, **_NO_REFCOUNT)  # type: ignore[call-overload]


@njit(cache=True, fastmath=True, inline="always")
def _overlap(lo: float, hi: float, a: float, b: float) -> float:
    return max(0.0, min(hi, b) - max(lo, a))


@njit(cache=True, fastmath=True, inline="always")
def _window_fraction(u: float, travel: float, a: float, b: float) -> float:
    """Fraction of the step's travel [u − travel/2, u + travel/2] that lies in [a, b]."""
    if travel <= 1e-15:
        return 1.0 if a <= u <= b else 0.0
    return _overlap(u - 0.5 * travel, u + 0.5 * travel, a, b) / travel


@njit(cache=True, fastmath=True, inline="always")
def _shape(x: float, exponent: float) -> float:
    if exponent == 1.0:
        return x
    if exponent == 2.0:
        return x * x
    return x**exponent


@_step_helper
def _relief(u: float, p: np.ndarray) -> float:
    start, end, exponent = p[P_START], p[P_END], p[P_RELIEF_EXP]
    removed = 0.0
    la1, la2 = p[P_LA1], p[P_LA2]
    if la1 > 0.0 and u > end - la1:
        removed += p[P_CA1] * _shape(min(u - (end - la1), la1) / la1, exponent)
    if la2 > 0.0 and u < start + la2:
        removed += p[P_CA2] * _shape(min((start + la2) - u, la2) / la2, exponent)
    return removed


@njit(cache=True, fastmath=True, inline="always")
def _profile_factor(u: float, p: np.ndarray) -> float:
    """Stiffness-per-length factor along the path of contact (mean 1 over the path)."""
    start, end = p[P_START], p[P_END]
    xi = min(max((2.0 * u - start - end) / (end - start), -1.0), 1.0)
    if p[P_KPROFILE] == KPROFILE_LINEAR:
        return 1.0 + p[P_KPROFILE_A] * xi
    return 1.0 - p[P_KPROFILE_A] * (xi * xi - 1.0 / 3.0)


@_step_helper
def _build_segments(
    s_m: float,
    travel_m: float,
    p: np.ndarray,
    pinion_teeth: int,
    gear_teeth: int,
    pitch1: np.ndarray,
    pitch2: np.ndarray,
    kfac1: np.ndarray,
    kfac2: np.ndarray,
    defect_wheel: np.ndarray,
    defect_tooth: np.ndarray,
    defect_u0: np.ndarray,
    defect_u1: np.ndarray,
    defect_z0: np.ndarray,
    defect_z1: np.ndarray,
    defect_depth: np.ndarray,
    ecc_m: float,
    seg: np.ndarray,
    breaks: np.ndarray,
    friction: bool,
) -> int:
    """Cut the contact lines into pieces of constant deviation; return how many.

    Each piece also gets its pair's contact position ``seg[S_U]`` and the sign of the sliding
    velocity ``seg[S_SLIDE]`` (−1 before the pitch point, +1 after, averaged over the step's
    travel so that the reversal is not quantised to the step)."""
    pb, u0, start, end = p[P_PB], p[P_U0], p[P_START], p[P_END]
    half_face = p[P_HALF_FACE]
    n_def = defect_wheel.shape[0]
    inv_pb = 1.0 / pb
    q_first = math.ceil((s_m + u0 - end - travel_m) * inv_pb)
    q_last = math.floor((s_m + u0 - start + travel_m) * inv_pb)
    # Tooth numbers of the first pair, then stepped (avoids an integer division per pair).
    tooth1 = q_first % pinion_teeth
    tooth2 = q_first % gear_teeth
    n_seg = 0
    for q in range(q_first, q_last + 1):
        if q > q_first:
            tooth1 += 1
            if tooth1 == pinion_teeth:
                tooth1 = 0
            tooth2 += 1
            if tooth2 == gear_teeth:
                tooth2 = 0
        u = s_m + u0 - q * pb
        weight = _window_fraction(u, travel_m, start, end)
        if weight <= 0.0:
            continue
        base_dev = _relief(u, p) + pitch1[tooth1] + pitch2[tooth2]
        k_line = p[P_KLEN] * kfac1[tooth1] * kfac2[tooth2] * weight
        if p[P_KPROFILE] != KPROFILE_CONSTANT:
            k_line *= _profile_factor(u, p)
        slide = 0.0
        if friction:
            slide = 2.0 * _window_fraction(u, travel_m, p[P_PITCH_POINT], 1e300) - 1.0
        n_break = 2
        breaks[0] = -half_face
        breaks[1] = half_face
        for d in range(n_def):
            tooth = tooth1 if defect_wheel[d] == 0 else tooth2
            if defect_tooth[d] != tooth:
                continue
            if _window_fraction(u, travel_m, defect_u0[d], defect_u1[d]) <= 0.0:
                continue
            breaks[n_break] = min(max(defect_z0[d], -half_face), half_face)
            breaks[n_break + 1] = min(max(defect_z1[d], -half_face), half_face)
            n_break += 2
        # Insertion sort: a handful of values.
        for i in range(1, n_break):
            value = breaks[i]
            j = i - 1
            while j >= 0 and breaks[j] > value:
                breaks[j + 1] = breaks[j]
                j -= 1
            breaks[j + 1] = value
        for i in range(n_break - 1):
            za, zb = breaks[i], breaks[i + 1]
            if zb - za <= 1e-12:
                continue
            mid = 0.5 * (za + zb)
            deviation = base_dev
            for d in range(n_def):
                tooth = tooth1 if defect_wheel[d] == 0 else tooth2
                if defect_tooth[d] != tooth or not (defect_z0[d] <= mid <= defect_z1[d]):
                    continue
                frac = _window_fraction(u, travel_m, defect_u0[d], defect_u1[d])
                deviation += defect_depth[d] * frac
            seg[S_Z0, n_seg] = za
            seg[S_Z1, n_seg] = zb
            seg[S_GAP, n_seg] = ecc_m - deviation
            seg[S_K, n_seg] = k_line
            seg[S_W, n_seg] = weight
            if friction:
                seg[S_U, n_seg] = u
                seg[S_SLIDE, n_seg] = slide
            n_seg += 1
    return n_seg


@_step_helper
def _contact_sums(
    n_seg: int,
    p0: float,
    p1: float,
    seg: np.ndarray,
    sums: np.ndarray,
    linear: bool,
) -> None:
    """Integrals of k, k z, k z², k g, k g z and the loaded length over the loaded parts.

    δ(z) = p0 + p1 z + gap is linear on each piece, so the loaded part is found exactly.
    ``sums[6]`` is the margin: the smallest |δ| at the ends of pieces that are wholly in
    or wholly out of contact (0 if a piece is cut), so a later change of δ smaller than it
    cannot change the contact set. ``linear``: every piece keeps its stiffness whatever δ
    (a linearised mesh, tension allowed); the set never changes (margin stays 1e300).
    """
    k0 = k1 = k2 = g0 = g1 = length = 0.0
    margin = 1e300
    for i in range(n_seg):
        za, zb = seg[S_Z0, i], seg[S_Z1, i]
        c = p0 + seg[S_GAP, i]
        if linear:
            pass
        else:
            da = c + p1 * za
            db = c + p1 * zb
            if (da > 0.0) == (db > 0.0):
                margin = min(margin, abs(da), abs(db))
            else:
                margin = 0.0
        if linear:
            pass
        elif abs(p1) < 1e-300:
            if c <= 0.0:
                continue
        else:
            z_zero = -c / p1
            if p1 > 0.0:
                za = max(za, z_zero)
            else:
                zb = min(zb, z_zero)
            if zb <= za:
                continue
        k = seg[S_K, i]
        d1 = zb - za
        d2 = 0.5 * (zb * zb - za * za)
        d3 = (zb * zb * zb - za * za * za) / 3.0
        k0 += k * d1
        k1 += k * d2
        k2 += k * d3
        g0 += k * seg[S_GAP, i] * d1
        g1 += k * seg[S_GAP, i] * d2
        length += seg[S_W, i] * d1
    sums[0] = k0
    sums[1] = k1
    sums[2] = k2
    sums[3] = g0
    sums[4] = g1
    sums[5] = length
    sums[6] = margin


@_step_helper
def _friction_sums(
    n_seg: int,
    p0: float,
    p1: float,
    w0: float,
    w1: float,
    eta: float,
    seg: np.ndarray,
    sums: np.ndarray,
    linear: bool,
) -> None:
    """Sliding-sign-weighted normal loads: Σ s·N, Σ s·u·N and Σ s·∫z dN over the loaded parts.

    The normal load per unit length is k(δ + η δ̇) with δ = p0 + p1 z + gap and
    δ̇ = w0 + w1 z (the mesh force's own law); s is the sign of the sliding velocity.
    ``linear``: the whole pieces, as in :func:`_contact_sums`.
    """
    n_s = n_su = m_s = 0.0
    for i in range(n_seg):
        za, zb = seg[S_Z0, i], seg[S_Z1, i]
        c = p0 + seg[S_GAP, i]
        if linear:
            pass
        elif abs(p1) < 1e-300:
            if c <= 0.0:
                continue
        else:
            z_zero = -c / p1
            if p1 > 0.0:
                za = max(za, z_zero)
            else:
                zb = min(zb, z_zero)
            if zb <= za:
                continue
        k = seg[S_K, i] * seg[S_SLIDE, i]
        d1 = zb - za
        d2 = 0.5 * (zb * zb - za * za)
        d3 = (zb * zb * zb - za * za * za) / 3.0
        constant = c + eta * w0
        slope = p1 + eta * w1
        load = k * (constant * d1 + slope * d2)
        n_s += load
        n_su += seg[S_U, i] * load
        m_s += k * (constant * d2 + slope * d3)
    sums[0] = n_s
    sums[1] = n_su
    sums[2] = m_s


@njit(cache=True, fastmath=True, inline="always")
def _biquad(coef: np.ndarray, state: np.ndarray, x: float) -> float:
    """Transposed direct form II; coef = b0, b1, b2, a1, a2 (a0 = 1)."""
    y = coef[0] * x + state[0]
    state[0] = coef[1] * x - coef[3] * y + state[1]
    state[1] = coef[2] * x - coef[4] * y
    return y


@njit(cache=True, fastmath=True)
def integrate(
    n_warm_steps: int,
    n_samples: int,
    oversampling: int,
    step_s: float,
    mass_diag: np.ndarray,
    stiffness: np.ndarray,
    damping: np.ndarray,
    a_inv: np.ndarray,
    v0: np.ndarray,
    v1: np.ndarray,
    dof_map: np.ndarray,
    p: np.ndarray,
    pinion_teeth: int,
    gear_teeth: int,
    pitch1: np.ndarray,
    pitch2: np.ndarray,
    kfac1: np.ndarray,
    kfac2: np.ndarray,
    defect_wheel: np.ndarray,
    defect_tooth: np.ndarray,
    defect_u0: np.ndarray,
    defect_u1: np.ndarray,
    defect_z0: np.ndarray,
    defect_z1: np.ndarray,
    defect_depth: np.ndarray,
    sensor_source: np.ndarray,
    mode_coef: np.ndarray,
    anti_alias: np.ndarray,
    tach_on_gear: bool,
    x_init: np.ndarray,
    v_init: np.ndarray,
    out: np.ndarray,
    sensor_out: np.ndarray,
    edges: np.ndarray,
) -> tuple[int, int, int]:
    """Integrate the warm-up then ``n_samples`` output samples of ``oversampling`` steps.

    Output sample i is the state at time ``(n_warm_steps + i·oversampling)·h`` (the record
    starts at ``n_warm_steps·h``, which must be ≥ 1 step), so that output samples fall at
    the same instants whatever the oversampling. Rows of ``out`` are the
    ``OUT_*`` quantities; ``sensor_out[s]`` is sensor s: its bearing force
    (``sensor_source[s]``: 0 pinion / 1 gear along the line of action, 2 pinion / 3 gear
    perpendicular to it) through the biquads
    ``mode_coef[s, m]`` summed over modes, then through the anti-alias cascade, both run
    at the integration rate. ``edges`` receives the tachometer reference crossings (record
    time, s), interpolated within the step. Returns (edge count, most contact-set
    iterations in a step, steps whose contact set did not settle).

    Sliding friction (``p[P_MU]`` > 0) is applied explicitly: the friction forces and moments
    of a step come from the normal loads at the Newmark predictor of its end state (contact
    positions and sliding signs of the step itself), which keeps the mesh solve a symmetric
    rank-2 update; the reported friction force is recomputed from the solved state.
    """
    # Long function: one compiled (numba) Newmark loop over the arrays it is given; its step is
    # described in docs/simulator.md, "Integration".
    n = mass_diag.shape[0]
    h = step_s
    eta = p[P_ETA]
    rb1 = p[P_RB1]
    rb2 = p[P_RB2]
    i_motor = dof_map[D_MOTOR]
    i_p = dof_map[D_PINION_ROT]
    i_g = dof_map[D_GEAR_ROT]
    i_load = dof_map[D_LOAD]
    i_px = dof_map[D_PINION_X]
    i_gx = dof_map[D_GEAR_X]
    i_py = dof_map[D_PINION_Y]
    i_gy = dof_map[D_GEAR_Y]
    i_prx = dof_map[D_PINION_RX]
    i_grx = dof_map[D_GEAR_RX]
    mu = p[P_MU]
    t1t2 = p[P_T1T2]
    linear_mesh = p[P_LINEAR_MESH] != 0.0
    fluct_order = p[P_FLUCT_ORDER]
    i_tach = i_g if tach_on_gear else i_p
    n_steps = n_warm_steps + (n_samples - 1) * oversampling
    n_rec_steps = max(1, (n_samples - 1) * oversampling)
    two_pi = 2.0 * math.pi
    ecc_on = p[P_ECC1] != 0.0 or p[P_ECC2] != 0.0

    # K and C are sparse (shaft couplings and bearings): keep their non-zeros by row.
    row_start = np.zeros(n + 1, dtype=np.int64)
    count = 0
    for i in range(n):
        for j in range(n):
            if stiffness[i, j] != 0.0 or damping[i, j] != 0.0:
                count += 1
        row_start[i + 1] = count
    nz_col = np.zeros(count, dtype=np.int64)
    nz_stiffness = np.zeros(count)
    nz_damping = np.zeros(count)
    count = 0
    for i in range(n):
        for j in range(n):
            if stiffness[i, j] != 0.0 or damping[i, j] != 0.0:
                nz_col[count] = j
                nz_stiffness[count] = stiffness[i, j]
                nz_damping[count] = damping[i, j]
                count += 1

    x = x_init.copy()
    v = v_init.copy()
    acc = np.zeros(n)
    dx = np.zeros(n)
    r = np.zeros(n)
    y_c = np.zeros(n)
    w_mat = np.zeros((n, 2))
    for i in range(n):
        s0 = 0.0
        s1 = 0.0
        for j in range(n):
            s0 += a_inv[i, j] * v0[j]
            s1 += a_inv[i, j] * v1[j]
        w_mat[i, 0] = s0
        w_mat[i, 1] = s1
    utw = np.zeros((2, 2))
    for i in range(n):
        utw[0, 0] += v0[i] * w_mat[i, 0]
        utw[0, 1] += v0[i] * w_mat[i, 1]
        utw[1, 0] += v1[i] * w_mat[i, 0]
        utw[1, 1] += v1[i] * w_mat[i, 1]

    max_seg = MAX_PAIRS * (2 * defect_wheel.shape[0] + 1)
    seg = np.zeros((N_SEG_ROWS, max_seg))
    fric = np.zeros(3)
    breaks = np.zeros(2 * defect_wheel.shape[0] + 2)
    sums = np.zeros(7)
    prev = np.zeros(7)
    half_face = p[P_HALF_FACE]
    damp_factor = 1.0 + 2.0 * eta / h
    max_iterations_used = 0
    unsettled = 0

    n_sensors = sensor_source.shape[0]
    n_modes = mode_coef.shape[1]
    n_sections = anti_alias.shape[0]
    mode_state = np.zeros((n_sensors, n_modes, 2))
    aa_state = np.zeros((n_sensors, n_sections, 2))
    force_ref = np.zeros(4)
    n_edges = 0
    tach_phase_prev = (x[i_tach] - p[P_TACH_OFFSET]) * p[P_TACH_PPR] / two_pi
    next_level = math.floor(tach_phase_prev) + 1.0
    p0_used = 0.0
    p1_used = 0.0

    for step in range(n_steps):
        t_next = (step + 1) * h
        # Motor: feed-forward torque + proportional speed loop on the reference speed.
        t_rec = min(max((t_next - n_warm_steps * h) / (n_rec_steps * h), 0.0), 1.0)
        omega_ref = p[P_SPEED] * (1.0 + p[P_DRIFT] * t_rec)
        if p[P_FLUCT] != 0.0:
            if fluct_order > 0.0:
                # Locked to the pinion angle (motor cogging, a cardan joint): synchronous,
                # so it survives the angle-domain average.
                th_ref = x[i_p] + h * v[i_p]
                omega_ref += p[P_SPEED] * p[P_FLUCT] * math.cos(
                    fluct_order * th_ref + p[P_FLUCT_PHASE]
                )
            else:
                omega_ref += p[P_SPEED] * p[P_FLUCT] * math.sin(two_pi * p[P_FLUCT_HZ] * t_next)
        # Kinematics from the predictor: the mesh position follows the actual rotation.
        th1 = x[i_p] + h * v[i_p] + 0.5 * h * h * acc[i_p]
        th2 = x[i_g] + h * v[i_g] + 0.5 * h * h * acc[i_g]
        ecc1 = 0.0
        ecc2 = 0.0
        if ecc_on:
            ecc1 = p[P_ECC1] * math.cos(th1 + p[P_PHI1])
            ecc2 = p[P_ECC2] * math.cos(th2 + p[P_PHI2])
        s_m = rb1 * th1 + ecc1
        travel = abs(rb1 * v[i_p]) * h
        n_seg = _build_segments(
            s_m, travel, p, pinion_teeth, gear_teeth, pitch1, pitch2, kfac1, kfac2,
            defect_wheel, defect_tooth, defect_u0, defect_u1, defect_z0, defect_z1,
            defect_depth, ecc1 - ecc2, seg, breaks, mu > 0.0,
        )  # fmt: skip

        # Constant part of the right-hand side.
        for i in range(n):
            kx_cv = 0.0
            for nz in range(row_start[i], row_start[i + 1]):
                j = nz_col[nz]
                kx_cv += nz_damping[nz] * v[j] - nz_stiffness[nz] * x[j]
            r[i] = mass_diag[i] * (4.0 / h * v[i] + acc[i]) + kx_cv
        r[i_motor] += p[P_TORQUE_FF] + p[P_CONTROL_GAIN] * omega_ref
        load_torque = p[P_LOAD]
        if p[P_LOAD_FLUCT] != 0.0:
            th_load = x[i_load] + h * v[i_load]
            load_torque *= 1.0 + p[P_LOAD_FLUCT] * math.cos(
                p[P_LOAD_ORDER] * th_load + p[P_LOAD_PHASE]
            )
        r[i_load] -= load_torque
        if mu > 0.0:
            # Friction μ·s·N on each contact, perpendicular to the line of action (−y on the
            # pinion, +y on the gear for s > 0), with moments about the wheel axes (arms u and
            # T1T2 − u) and, off the face centre, about the line of action (rx). Explicit:
            # the normal loads come from the Newmark predictor at the end of this step.
            pp0 = 0.0
            pp1 = 0.0
            pw0 = 0.0
            pw1 = 0.0
            for i in range(n):
                x_pred = x[i] + h * v[i] + 0.5 * h * h * acc[i]
                v_pred = v[i] + h * acc[i]
                pp0 += v0[i] * x_pred
                pp1 += v1[i] * x_pred
                pw0 += v0[i] * v_pred
                pw1 += v1[i] * v_pred
            _friction_sums(
                n_seg, pp0, pp1, pw0, pw1, eta, seg, fric, linear_mesh,
            )  # fmt: skip
            r[i_p] -= mu * fric[1]
            r[i_g] += mu * (t1t2 * fric[0] - fric[1])
            if i_py >= 0:
                r[i_py] -= mu * fric[0]
                r[i_gy] += mu * fric[0]
            if i_prx >= 0:
                r[i_prx] += mu * fric[2]
                r[i_grx] -= mu * fric[2]
        p0n = 0.0
        p1n = 0.0
        w0 = 0.0
        w1 = 0.0
        uy0 = 0.0
        uy1 = 0.0
        pd0 = 0.0
        pd1 = 0.0
        for i in range(n):
            yi = 0.0
            for j in range(n):
                yi += a_inv[i, j] * r[j]
            y_c[i] = yi
            p0n += v0[i] * x[i]
            p1n += v1[i] * x[i]
            w0 += v0[i] * v[i]
            w1 += v1[i] * v[i]
            uy0 += v0[i] * yi
            uy1 += v1[i] * yi
            pred = h * v[i] + 0.5 * h * h * acc[i]
            pd0 += v0[i] * pred
            pd1 += v1[i] * pred
        p0e = p0n + pd0
        p1e = p1n + pd1

        iterations = 0
        settled = False
        for it in range(12):
            if it > 0 and abs(p0e - p0_used) + abs(p1e - p1_used) * half_face < prev[6]:
                # δ moved less than the margin: the contact set cannot have changed.
                settled = True
                break
            _contact_sums(n_seg, p0e, p1e, seg, sums, linear_mesh)
            if it > 0:
                same = True
                for k in range(5):
                    if abs(sums[k] - prev[k]) > 1e-12 * (abs(prev[k]) + 1e-30):
                        same = False
                if same:
                    settled = True
                    break
            for k in range(7):
                prev[k] = sums[k]
            p0_used = p0e
            p1_used = p1e
            iterations = it + 1
            k0, k1, k2, g0, g1 = sums[0], sums[1], sums[2], sums[3], sums[4]
            alpha0 = -(k0 * p0n + k1 * p1n + g0) + eta * (k0 * w0 + k1 * w1)
            alpha1 = -(k1 * p0n + k2 * p1n + g1) + eta * (k1 * w0 + k2 * w1)
            b0 = uy0 + utw[0, 0] * alpha0 + utw[0, 1] * alpha1
            b1 = uy1 + utw[1, 0] * alpha0 + utw[1, 1] * alpha1
            s00 = damp_factor * k0
            s01 = damp_factor * k1
            s11 = damp_factor * k2
            # B = I + UᵀW S; solve B β = Uᵀy, then γ = S β (Woodbury, rank 2).
            m00 = 1.0 + utw[0, 0] * s00 + utw[0, 1] * s01
            m01 = utw[0, 0] * s01 + utw[0, 1] * s11
            m10 = utw[1, 0] * s00 + utw[1, 1] * s01
            m11 = 1.0 + utw[1, 0] * s01 + utw[1, 1] * s11
            det = m00 * m11 - m01 * m10
            beta0 = (m11 * b0 - m01 * b1) / det
            beta1 = (m00 * b1 - m10 * b0) / det
            c0 = alpha0 - (s00 * beta0 + s01 * beta1)
            c1 = alpha1 - (s01 * beta0 + s11 * beta1)
            p0e = p0n
            p1e = p1n
            for i in range(n):
                dx[i] = y_c[i] + w_mat[i, 0] * c0 + w_mat[i, 1] * c1
                p0e += v0[i] * dx[i]
                p1e += v1[i] * dx[i]
        if iterations > max_iterations_used:
            max_iterations_used = iterations
        if not settled:
            unsettled += 1

        w0 = 0.0
        w1 = 0.0
        for i in range(n):
            v_new = 2.0 / h * dx[i] - v[i]
            acc[i] = 4.0 / (h * h) * (dx[i] - h * v[i]) - acc[i]
            v[i] = v_new
            x[i] += dx[i]
            w0 += v0[i] * v_new
            w1 += v1[i] * v_new

        k0, k1, g0 = prev[0], prev[1], prev[3]
        mesh_force = k0 * p0e + k1 * p1e + g0 + eta * (k0 * w0 + k1 * w1)
        friction_force = 0.0
        if mu > 0.0:
            _friction_sums(
                n_seg, p0e, p1e, w0, w1, eta, seg, fric, linear_mesh,
            )  # fmt: skip
            friction_force = mu * fric[0]
        if i_px >= 0:
            force_p = p[P_KB1] * x[i_px] + p[P_CB1] * v[i_px]
        else:
            force_p = -mesh_force
        if i_gx >= 0:
            force_g = p[P_KB2] * x[i_gx] + p[P_CB2] * v[i_gx]
        else:
            force_g = mesh_force
        # Off the line of action: the support's force, or with rigid supports the friction.
        if i_py >= 0:
            force_p += p[P_KXY1] * x[i_py] + p[P_CXY1] * v[i_py]
            force_g += p[P_KXY2] * x[i_gy] + p[P_CXY2] * v[i_gy]
            force_p_off = p[P_KYY1] * x[i_py] + p[P_CYY1] * v[i_py]
            force_g_off = p[P_KYY2] * x[i_gy] + p[P_CYY2] * v[i_gy]
            if i_px >= 0:
                force_p_off += p[P_KXY1] * x[i_px] + p[P_CXY1] * v[i_px]
                force_g_off += p[P_KXY2] * x[i_gx] + p[P_CXY2] * v[i_gx]
        else:
            force_p_off = -friction_force
            force_g_off = friction_force
        if step == 0:
            # Filters start from rest at the initial (static) force: no start-up step.
            force_ref[0] = force_p
            force_ref[1] = force_g
            force_ref[2] = force_p_off
            force_ref[3] = force_g_off

        # Transfer path and anti-alias filter at the integration rate.
        since_start = step + 1 - n_warm_steps
        is_sample = since_start >= 0 and since_start % oversampling == 0
        sample = since_start // oversampling
        for s_i in range(n_sensors):
            source = sensor_source[s_i]
            if source == 0:
                f_dyn = force_p - force_ref[0]
            elif source == 1:
                f_dyn = force_g - force_ref[1]
            elif source == 2:
                f_dyn = force_p_off - force_ref[2]
            else:
                f_dyn = force_g_off - force_ref[3]
            total = 0.0
            for m_i in range(n_modes):
                total += _biquad(mode_coef[s_i, m_i], mode_state[s_i, m_i], f_dyn)
            for q_i in range(n_sections):
                total = _biquad(anti_alias[q_i], aa_state[s_i, q_i], total)
            if is_sample:
                sensor_out[s_i, sample] = total

        # Tachometer: reference crossings of the tach shaft, interpolated within the step.
        tach_phase = (x[i_tach] - p[P_TACH_OFFSET]) * p[P_TACH_PPR] / two_pi
        if tach_phase >= next_level:
            level = math.floor(tach_phase)
            if n_edges < edges.shape[0]:
                frac = (level - tach_phase_prev) / (tach_phase - tach_phase_prev)
                edges[n_edges] = (step + frac - n_warm_steps) * h
                n_edges += 1
            next_level = level + 1.0
        tach_phase_prev = tach_phase

        if is_sample:
            out[OUT_PINION_ANGLE, sample] = x[i_p]
            out[OUT_GEAR_ANGLE, sample] = x[i_g]
            out[OUT_TE, sample] = rb1 * x[i_p] - rb2 * x[i_g]
            out[OUT_MESH_FORCE, sample] = mesh_force
            out[OUT_BEARING_PINION, sample] = force_p
            out[OUT_BEARING_GEAR, sample] = force_g
            out[OUT_CONTACT_LENGTH, sample] = prev[5]
            out[OUT_BEARING_PINION_OFF, sample] = force_p_off
            out[OUT_BEARING_GEAR_OFF, sample] = force_g_off
            out[OUT_FRICTION_FORCE, sample] = friction_force
    return n_edges, max_iterations_used, unsettled
