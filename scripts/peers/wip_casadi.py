#!/usr/bin/env python3
"""The WIP planning benchmarks (docs/problems.md) in CasADi, solved by IPOPT or FATROP.

The same problem as `wip plan NAME --integrator rk1` (docs/ocp.md, "Transcriptions"):

* state x_k = (x, y, θ, α, φR, φL, qR, qL, v_α, v_φR, v_φL, iR, iL, uR_{k−1}, uL_{k−1}),
  decision u_k = (uR_k, uL_k), dynamics x_{k+1} = x_k + h·ẋ(x_k, u_k) with the previous-input
  slots set to u_k (explicit Euler on the continuous model, inputs held over the step);
* cost ½ Σ_{k<N} (uR_k iR_k + uL_k iL_k) with the state's currents at stage k;
* at every stage k < N: |u| ≤ 5 V, |(u_k − u_{k−1})/h| ≤ 2 V/s, |i| ≤ 3 A, |α| ≤ 15°,
  |v_θ| ≤ 120°/s;
* x_0 = the start pose at rest; (x, y) at the waypoint stages; at N the end pose, α = 0 and
  all shape velocities (currents included) zero.

The continuous model is derived here, symbolically, from the Lagrangian of docs/wip.md in
the full coordinates q = (x, y, θ, α, φR, φL, qR, qL): CasADi differentiates L, and the
Lagrange–d'Alembert equations are projected on the constraint's null space, q̇ = S(q) v.
(The Rust model derives the same equations from the reduced Lagrangian ℓ(s, v, ξ) with dual
numbers; `verify` checks the two against each other.)

Variables are stage-ordered (x_0, u_0, x_1, u_1, …, x_N) and the constraints are grouped by
stage (dynamics gap, path constraints, equalities), so that FATROP's structure detection
sees the optimal-control structure. IPOPT gets the very same NLP.

Commands:
  solve   one solve; prints a JSON line (and writes it with --json FILE)
  verify  checks the CasADi model and optimum against the Rust binary; exits 1 on a mismatch
"""

import argparse
import bisect
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import casadi as ca
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

# ---------------------------------------------------------------------------------------
# Parameters (docs/wip.md; `wip params` prints the same keys)

DEFAULT_PARAMS = {
    "g": 9.81,
    "m_b": 277e-3,
    "I_bxx": 543.108e-6,
    "I_byy": 481.457e-6,
    "I_bzz": 153.951e-6,
    "m_w": 28e-3,
    "I_wxx": 4.957e-6,
    "I_wyy": 7.411e-6,
    "I_wzz": 4.957e-6,
    "l": 48.67e-3,
    "r": 33e-3,
    "d": 49e-3,
    "d_v": 1.532e-3,
    "d_c": 32.6e-3,
    "d_0": 8.0,
    "I_m": 268.528e-9,
    "I_g": 1.807e-6,
    "n_wm": (78.0 / 11.0) ** 2,
    "n_wg": 78.0 / 11.0,
    "k_e": 3.76e-3,
    "L_m": 4e-4,
    "R_m": 1.5,
}


def load_params(path=None):
    p = dict(DEFAULT_PARAMS)
    if path:
        with open(path) as f:
            given = json.load(f)
        unknown = set(given) - set(p)
        if unknown:
            raise SystemExit(f"{path}: unknown parameter keys {sorted(unknown)}")
        p.update(given)
    return p


# ---------------------------------------------------------------------------------------
# The model


def lagrangian(p, q, qd):
    """L = T − V of docs/wip.md in the full coordinates q = (x, y, θ, α, φR, φL, qR, qL)."""
    th, al, qr, ql = q[2], q[3], q[6], q[7]
    xd, yd, thd, ald, phrd, phld, ir, il = (qd[i] for i in range(8))
    sa, ca_, st, ct = ca.sin(al), ca.cos(al), ca.sin(th), ca.cos(th)
    l = p["l"]
    vb = ca.vertcat(
        xd + l * ald * ca_ * ct - l * thd * sa * st,
        yd + l * ald * ca_ * st + l * thd * sa * ct,
        -l * ald * sa,
    )
    wb = ca.vertcat(-thd * sa, ald, thd * ca_)
    t_body = 0.5 * p["m_b"] * ca.sumsqr(vb) + 0.5 * (
        p["I_bxx"] * wb[0] ** 2 + p["I_byy"] * wb[1] ** 2 + p["I_bzz"] * wb[2] ** 2
    )
    d = p["d"]
    vwr = ca.vertcat(xd + d * thd * ct, yd + d * thd * st)
    vwl = ca.vertcat(xd - d * thd * ct, yd - d * thd * st)
    t_wheels = (
        0.5 * p["m_w"] * (ca.sumsqr(vwr) + ca.sumsqr(vwl))
        + 0.5 * p["I_wyy"] * (phrd**2 + phld**2)
        + 2 * 0.5 * p["I_wzz"] * thd**2
    )

    def stage(phid):
        rel = phid - ald
        return 0.5 * p["I_m"] * (ald + p["n_wm"] * rel) ** 2 + 0.5 * p["I_g"] * (
            ald - p["n_wg"] * rel
        ) ** 2

    t_gear = stage(phrd) + stage(phld)
    t_motor = 0.5 * p["L_m"] * (ir**2 + il**2)
    v_grav = p["m_b"] * p["g"] * l * ca_
    v_emf = p["k_e"] * p["n_wm"] * ((phrd - ald) * qr + (phld - ald) * ql)
    return t_body + t_wheels + t_gear + t_motor - v_grav - v_emf


def friction(p, w):
    return p["d_v"] * w + p["d_c"] * ca.tanh(p["d_0"] * w)


class Model:
    """SX functions of the WIP: the shape acceleration, the state rate and one RK step."""

    NX = 15  # (x, y, θ, s(5), v(5), u_prev(2))
    NU = 2

    def __init__(self, p):
        self.p = p
        q = ca.SX.sym("q", 8)
        v = ca.SX.sym("v", 5)  # (v_α, v_φR, v_φL, iR, iL)
        u = ca.SX.sym("u", 2)
        r, d = p["r"], p["d"]
        th = q[2]
        xi1 = r * (v[1] + v[2]) / 2  # forward speed
        xi3 = r * (v[1] - v[2]) / (2 * d)  # heading rate
        # q̇ = S(q) v: rolling without slip, no side slip.
        qdot = ca.vertcat(ca.cos(th) * xi1, ca.sin(th) * xi1, xi3, v)
        S = ca.jacobian(qdot, v)
        qd = ca.SX.sym("qd", 8)
        L = lagrangian(p, q, qd)
        mom = ca.gradient(L, qd)  # ∂L/∂q̇
        M = ca.jacobian(mom, qd)
        Jmq = ca.jacobian(mom, q)
        dLdq = ca.gradient(L, q)
        # Generalised forces: friction on (α, φR, φL), voltage minus resistance on (qR, qL).
        fr, fl = friction(p, v[1] - v[0]), friction(p, v[2] - v[0])
        F = ca.vertcat(0, 0, 0, fr + fl, -fr, -fl, u[0] - p["R_m"] * v[3], u[1] - p["R_m"] * v[4])
        # Lagrange–d'Alembert on the constraint: Sᵀ (d/dt ∂L/∂q̇ − ∂L/∂q − F) = 0 with
        # q̈ = S v̇ + (∂(S v)/∂q) q̇ at fixed v.
        sdot_v = ca.jacobian(qdot, q) @ qdot
        subst = lambda e: ca.substitute(e, qd, qdot)
        Mq, Jq, Lq = subst(M), subst(Jmq), subst(dLdq)
        Mr = S.T @ Mq @ S
        rhs = -(S.T @ (Mq @ sdot_v + Jq @ qdot - Lq - F))
        a = ca.solve(Mr, rhs)
        self.accel = ca.Function("accel", [q, v, u], [a], ["q", "v", "u"], ["a"])

        x = ca.SX.sym("x", self.NX)
        ax = self.accel(x[0:8], x[8:13], u)
        vx = x[8:13]
        thx = x[2]
        f1 = r * (vx[1] + vx[2]) / 2
        f3 = r * (vx[1] - vx[2]) / (2 * d)
        xdot = ca.vertcat(ca.cos(thx) * f1, ca.sin(thx) * f1, f3, vx, ax, ca.DM.zeros(2))
        self.rate = ca.Function("rate", [x, u], [xdot], ["x", "u"], ["xdot"])

        # The reduced state of `wip simulate` and docs/wip.md:
        # X = (x, y, θ, α, v_α, v_d, v_θ, iR, iL).
        X = ca.SX.sym("X", 9)
        vr = (X[5] + d * X[6]) / r
        vl = (X[5] - d * X[6]) / r
        xfull = ca.vertcat(X[0:4], 0, 0, 0, 0, X[4], vr, vl, X[7], X[8], 0, 0)
        xd_full = self.rate(xfull, u)
        aa = xd_full[8:13]
        Xdot = ca.vertcat(
            xd_full[0:3],
            X[4],
            aa[0],
            r * (aa[1] + aa[2]) / 2,
            r * (aa[1] - aa[2]) / (2 * d),
            aa[3],
            aa[4],
        )
        self.reduced_rate = ca.Function("reduced_rate", [X, u], [Xdot])

    def step(self, h, method="rk1"):
        """x_{k+1} = F(x_k, u_k): one explicit RK step with u held, u_prev ← u."""
        x = ca.SX.sym("x", self.NX)
        u = ca.SX.sym("u", self.NU)
        f = lambda y: self.rate(y, u)
        if method == "rk1":
            nxt = x + h * f(x)
        elif method == "rk2":
            nxt = x + h * f(x + 0.5 * h * f(x))
        elif method == "rk4":
            k1 = f(x)
            k2 = f(x + 0.5 * h * k1)
            k3 = f(x + 0.5 * h * k2)
            k4 = f(x + h * k3)
            nxt = x + (h / 6) * (k1 + 2 * k2 + 2 * k3 + k4)
        else:
            raise ValueError(method)
        nxt = ca.vertcat(nxt[0:13], u)
        return ca.Function("F", [x, u], [nxt], ["x", "u"], ["xnext"])


def full_from_reduced(p, X):
    """The 15-state (φ, q, u_prev zero) of a reduced state X."""
    r, d = p["r"], p["d"]
    vr = (X[5] + d * X[6]) / r
    vl = (X[5] - d * X[6]) / r
    return np.array([X[0], X[1], X[2], X[3], 0, 0, 0, 0, X[4], vr, vl, X[7], X[8], 0, 0])


def reduced_from_full(p, x):
    r, d = p["r"], p["d"]
    return np.array(
        [
            x[0],
            x[1],
            x[2],
            x[3],
            x[8],
            r * (x[9] + x[10]) / 2,
            r * (x[9] - x[10]) / (2 * d),
            x[11],
            x[12],
        ]
    )


# ---------------------------------------------------------------------------------------
# The problems (robots/src/wip/benchmarks.rs)


def rust_round(x):
    """f64::round: half away from zero."""
    return math.copysign(math.floor(abs(x) + 0.5), x)


def arc_lengths(points):
    s = [0.0]
    for a, b in zip(points, points[1:]):
        s.append(s[-1] + math.hypot(b[0] - a[0], b[1] - a[1]))
    return s


def trapezoid_times(s, total_time, a):
    total = s[-1]
    disc = total_time * total_time - 4.0 * total / a
    if disc < 0:
        raise ValueError("no trapezoidal profile")
    vc = 0.5 * a * (total_time - math.sqrt(disc))
    t1 = vc / a
    s1 = 0.5 * a * t1 * t1
    s2 = total - s1
    out = []
    for sj in s:
        if sj <= s1:
            out.append(math.sqrt(2.0 * sj / a))
        elif sj <= s2:
            out.append(t1 + (sj - s1) / vc)
        else:
            out.append(total_time - math.sqrt(2.0 * max(total - sj, 0.0) / a))
    return out


class Problem:
    def __init__(self, name, points, total_time, accel, h, start_heading, end_heading):
        self.name, self.points, self.h = name, points, h
        self.start_heading, self.end_heading = start_heading, end_heading
        times = trapezoid_times(arc_lengths(points), total_time, accel)
        self.n = int(rust_round(total_time / h))
        self.stages = [int(rust_round(t / h)) for t in times]


def problem_by_name(name, h):
    if name == "eight":
        pts = [[1.0, 0.5], [2.0, 1.5], [3.0, 2.5], [4.0, 1.5], [3.0, 0.5], [2.0, 1.5],
               [1.0, 2.5], [0.0, 1.5], [1.0, 0.5]]
        q = math.pi / 4
        return Problem("eight", pts, 21.175, 0.2, h, q, -q)
    if name == "zigzag":
        pts = [[4.0 - 0.33541 * j, 1.5 + 0.1 * (j % 2)] for j in range(19)]
        return Problem("zigzag", pts, 19.36, 0.1, h, math.pi, math.pi)
    raise SystemExit(f"unknown problem {name!r} (eight or zigzag)")


# ---------------------------------------------------------------------------------------
# Starts


def polyline_start(p, prob):
    """The planner's polyline start (robots/src/wip/plan_start.rs, `polyline_start`):
    arc length a monotone cubic in time through the waypoints, positions smoothed over
    ±0.25 s, heading along the motion, wheel angles by rolling; returns (g_k, s_k)."""
    n, h = prob.n, prob.h
    pts, stages = prob.points, prob.stages
    s_at = arc_lengths(pts)
    m = len(stages)
    secant = [(s_at[j] - s_at[j - 1]) / (stages[j] - stages[j - 1]) for j in range(1, m)]
    slope = []
    for j in range(m):
        if j == 0 or j == m - 1:
            slope.append(0.0)
        else:
            a, b = secant[j - 1], secant[j]
            slope.append(0.0 if a * b <= 0 else 2 * a * b / (a + b))

    def arc_of_stage(k):
        j = min(max(bisect.bisect_right(stages, k), 1), m - 1)
        k0, k1 = stages[j - 1], stages[j]
        dk = float(k1 - k0)
        f = min(max((k - k0) / dk, 0.0), 1.0)
        h00 = (1 + 2 * f) * (1 - f) * (1 - f)
        h10 = f * (1 - f) * (1 - f)
        h01 = f * f * (3 - 2 * f)
        h11 = f * f * (f - 1)
        return h00 * s_at[j - 1] + h10 * dk * slope[j - 1] + h01 * s_at[j] + h11 * dk * slope[j]

    def point_at(s):
        j = min(max(bisect.bisect_right(s_at, s), 1), len(s_at) - 1)
        ln = s_at[j] - s_at[j - 1]
        f = min(max((s - s_at[j - 1]) / ln, 0.0), 1.0)
        a, b = pts[j - 1], pts[j]
        return [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]

    raw = np.array([point_at(arc_of_stage(k)) for k in range(n + 1)])
    half = max(int(rust_round(0.25 / h)), 1)

    smooth = np.empty_like(raw)
    for k in range(n + 1):
        lo, hi = max(k - half, 0), min(k + half, n)
        smooth[k] = raw[lo:hi + 1].sum(axis=0) / (hi - lo + 1)
    tau = 2 * math.pi
    raw_theta = [prob.start_heading] * (n + 1)
    prev = prob.start_heading
    for k in range(n):
        dx, dy = smooth[k + 1] - smooth[k]
        if math.hypot(dx, dy) > 1e-9:
            ang = math.atan2(dy, dx)
            dd = ang - prev
            dd -= rust_round(dd / tau) * tau
            prev += dd
        raw_theta[k + 1] = prev
    end = prob.end_heading
    end += rust_round((prev - end) / tau) * tau
    ramp = float(2 * half)
    theta = []
    for k in range(n + 1):
        a = min(k / ramp, 1.0)
        b = min((n - k) / ramp, 1.0)
        th = a * raw_theta[k] + (1 - a) * prob.start_heading
        theta.append(b * th + (1 - b) * end)
    r, d = p["r"], p["d"]
    dist = 0.0
    out = []
    for k in range(n + 1):
        if k > 0:
            dist += math.hypot(*(smooth[k] - smooth[k - 1]))
        th = theta[k] - prob.start_heading
        g = np.array([smooth[k][0], smooth[k][1], theta[k]])
        s = np.array([0.0, (dist + d * th) / r, (dist - d * th) / r, 0.0, 0.0])
        out.append((g, s))

    return out


def linear_start(p, prob):
    """A crude start: positions linear in time between the waypoints at their stages,
    heading along each segment (jumping at the waypoints), wheel angles by rolling."""
    n = prob.n
    pts, stages = prob.points, prob.stages
    r, d = p["r"], p["d"]
    out = []
    dist = 0.0
    prev = None
    for k in range(n + 1):
        j = min(max(bisect.bisect_right(stages, k), 1), len(stages) - 1)
        f = (k - stages[j - 1]) / (stages[j] - stages[j - 1])
        a, b = pts[j - 1], pts[j]
        xy = np.array([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])])
        th = math.atan2(b[1] - a[1], b[0] - a[0])
        if k == 0:
            th = prob.start_heading
        elif k == n:
            th = prob.end_heading
        if prev is not None:
            # unwrap next to the previous heading
            th += rust_round((prev - th) / (2 * math.pi)) * 2 * math.pi
            dist += math.hypot(*(xy - out[-1][0][:2]))
        prev = th
        dth = th - prob.start_heading
        out.append((np.array([xy[0], xy[1], th]),
                    np.array([0.0, (dist + d * dth) / r, (dist - d * dth) / r, 0.0, 0.0])))
    return out


def rk_start(p, prob, kind="polyline"):
    """The planner's RK start (plan_start.rs, `rk_start`): the path's states with
    v_k = (s_{k+1} − s_k)/h (zero at both ends), currents on their slow manifold for u = 0,
    u = 0. The first state is the problem's start state (as the solver's initial iterate)."""
    path = polyline_start(p, prob) if kind == "polyline" else linear_start(p, prob)
    n, h = prob.n, prob.h
    xs = np.zeros((n + 1, Model.NX))
    kem = p["k_e"] * p["n_wm"]
    for k in range(n + 1):
        g, s = path[k]
        xs[k, 0:3] = g
        xs[k, 3:8] = s
        if 0 < k < n:
            v = (path[k + 1][1] - s) / h
            v[3] = (0.0 - kem * (v[1] - v[0])) / p["R_m"]
            v[4] = (0.0 - kem * (v[2] - v[0])) / p["R_m"]
            xs[k, 8:13] = v
    xs[0] = start_state(prob)
    us = np.zeros((n, Model.NU))
    return xs, us


def start_state(prob):
    x = np.zeros(Model.NX)
    x[0], x[1] = prob.points[0]
    x[2] = prob.start_heading
    return x


# ---------------------------------------------------------------------------------------
# The NLP


BOUNDS = {
    "u_max": 5.0,
    "du_max_per_s": 2.0,
    "i_max": 3.0,
    "alpha_max": math.radians(15.0),
    "v_theta_max": math.radians(120.0),
}


def build_nlp(p, prob, method="rk1", rate_form="rate"):
    """The stage-ordered NLP. Returns (nlp dict, lbg, ubg, equality flags, layout).

    rate_form: "rate" writes the rate limit as (u_k − u_{k−1})/h ∈ [−2, 2] (as the planner);
    "diff" as u_k − u_{k−1} ∈ [−2h, 2h] (as docs/problems.md states it)."""
    model = Model(p)
    nx, nu, n, h = Model.NX, Model.NU, prob.n, prob.h
    F = model.step(h, method)
    x = ca.SX.sym("x", nx)
    u = ca.SX.sym("u", nu)
    r, d = p["r"], p["d"]
    cost = ca.Function("cost", [x, u], [0.5 * (u[0] * x[11] + u[1] * x[12])])
    rate_scale = 1.0 / h if rate_form == "rate" else 1.0
    du = BOUNDS["du_max_per_s"] * (1.0 if rate_form == "rate" else h)
    path = ca.Function(
        "path",
        [x, u],
        [ca.vertcat(u[0], u[1], (u[0] - x[13]) * rate_scale, (u[1] - x[14]) * rate_scale,
                    x[11], x[12], x[3], r * (x[9] - x[10]) / (2 * d))],
    )
    hi_path = [BOUNDS["u_max"]] * 2 + [du] * 2 + [BOUNDS["i_max"]] * 2 + [
        BOUNDS["alpha_max"], BOUNDS["v_theta_max"]]

    # Stage-k equalities on x_k: the start state at 0, waypoints, the end at N.
    x0 = start_state(prob)
    extra = {0: [(i, x0[i]) for i in range(nx)]}
    for pt, k in zip(prob.points, prob.stages):
        if 0 < k < n:
            extra.setdefault(k, []).extend([(0, pt[0]), (1, pt[1])])
    end = prob.points[-1]
    extra[n] = [(0, end[0]), (1, end[1]), (2, prob.end_heading), (3, 0.0)] + [
        (8 + i, 0.0) for i in range(5)]

    # The stage functions mapped over the stages: the generated C code holds each stage
    # function (and its derivatives) once, in a loop. (One call per stage in the graph gave
    # C code that gcc took more than 10 minutes to compile.)
    w = ca.MX.sym("w", (nx + nu) * n + nx)
    XU = ca.reshape(w[: (nx + nu) * n], nx + nu, n)
    X, U = XU[:nx, :], XU[nx:, :]
    xN = w[(nx + nu) * n:]
    gap = ca.horzcat(X[:, 1:], xN) - F.map(n)(X, U)  # nx × n
    C = path.map(n)(X, U)  # 8 × n
    f = ca.sum2(cost.map(n)(X, U))

    # Constraints by stage: [gap_k; path_k; equalities on x_k], stage after stage (what
    # FATROP's structure detection reads). Stage k's block of vec([gap; path]) is
    # contiguous; it is split where a stage has equalities.
    G = ca.vec(ca.vertcat(gap, C))
    per = nx + 8
    lo_path = [-b for b in hi_path]
    pieces, lbg, ubg, eq = [], [], [], []
    ng = [8] * n + [0]
    done = 0

    def stages_upto(upto):
        nonlocal done, lbg, ubg, eq
        if upto > done:
            pieces.append(G[done * per: upto * per])
            for _ in range(done, upto):
                lbg += [0.0] * nx + lo_path
                ubg += [0.0] * nx + hi_path
                eq += [True] * nx + [False] * 8
            done = upto

    for k in sorted(extra):
        stages_upto(min(k + 1, n))
        xk = X[:, k] if k < n else xN
        idx = [i for i, _ in extra[k]]
        vals = [v for _, v in extra[k]]
        pieces.append(xk[idx])
        lbg += vals
        ubg += vals
        eq += [True] * len(idx)
        ng[k] += len(idx)
    g = ca.vertcat(*pieces)
    assert g.shape[0] == len(lbg) == n * per + sum(len(e) for e in extra.values())
    structure = {"N": n, "nx": [nx] * (n + 1), "nu": [nu] * n + [0], "ng": ng}
    return {"x": w, "f": f, "g": g}, np.array(lbg), np.array(ubg), eq, structure


def pack(xs, us):
    n = us.shape[0]
    return np.concatenate([np.hstack([xs[:n], us]).ravel(), xs[n]])


def unpack(wv, n):
    nx, nu = Model.NX, Model.NU
    XU = wv[: (nx + nu) * n].reshape(n, nx + nu)
    xs = np.vstack([XU[:, :nx], wv[(nx + nu) * n:][None, :]])
    return xs, XU[:, nx:]


def solver_options(solver, jit, tol, verbose, max_iter, structure="auto"):
    # record_time: the stats then carry t_wall_total (the whole nlpsol call) and the
    # evaluation times.
    opts = {"record_time": True, "print_time": False}
    if jit:
        opts.update({"jit": True, "compiler": "shell",
                     "jit_options": {"flags": ["-O2"], "verbose": False}})
    if solver == "ipopt":
        opts["ipopt"] = {
            "tol": tol,
            "linear_solver": "mumps",
            "hessian_approximation": "exact",
            "max_iter": max_iter,
            "print_level": 5 if verbose else 0,
            "sb": "yes",
        }
    elif solver == "fatrop":
        opts["structure_detection"] = structure
        opts["fatrop"] = {"tol": tol, "max_iter": max_iter,
                          "print_level": 10 if verbose else 0}
    else:
        raise SystemExit(f"unknown solver {solver!r}")
    return opts


class Peer:
    """One problem, one solver: constructed once (model, NLP, nlpsol with its C code
    generation), then solved from the start as often as asked."""

    def __init__(self, args):
        self.args = args
        p = load_params(args.params)
        t0 = time.perf_counter()
        self.prob = problem_by_name(args.problem, args.step)
        xs, us = rk_start(p, self.prob, args.start)
        self.x0 = pack(xs, us)
        nlp, self.lbg, self.ubg, eq, structure = build_nlp(p, self.prob, args.integrator,
                                                           args.rate_form)
        opts = solver_options(args.solver, not args.no_jit, args.tol, args.verbose,
                              args.max_iter, args.structure)
        if args.solver == "fatrop":
            opts["equality"] = eq
            if args.structure == "manual":
                opts.update(structure)
        t1 = time.perf_counter()
        self.solver = ca.nlpsol("solver", args.solver, nlp, opts)
        t2 = time.perf_counter()
        self.t_build, self.t_nlpsol = t1 - t0, t2 - t1

    def solve(self):
        args, prob = self.args, self.prob
        t2 = time.perf_counter()
        res = self.solver(x0=self.x0, lbg=self.lbg, ubg=self.ubg)
        t3 = time.perf_counter()
        st = self.solver.stats()
        wv = np.array(res["x"]).ravel()
        xs_opt, us_opt = unpack(wv, prob.n)
        obj = float(0.5 * np.sum(us_opt[:, 0] * xs_opt[:-1, 11]
                                 + us_opt[:, 1] * xs_opt[:-1, 12]))
        gv = np.array(res["g"]).ravel()
        viol = float(np.max(np.maximum(0, np.maximum(self.lbg - gv, gv - self.ubg))))
        out = {
            "solver": args.solver,
            "problem": args.problem,
            "integrator": args.integrator,
            "h": prob.h,
            "N": prob.n,
            "start": args.start,
            "rate_form": args.rate_form,
            "structure": args.structure if args.solver == "fatrop" else None,
            "jit": not args.no_jit,
            "tol": args.tol,
            "casadi": ca.__version__,
            "status": st.get("return_status"),
            "success": bool(st.get("success")),
            "iterations": int(st.get("iter_count", -1)),
            "objective": obj,
            "max_violation": viol,
            "t_wall_total": float(st.get("t_wall_total", float("nan"))),
            "t_call_wall": t3 - t2,
            "t_build_s": self.t_build,
            "t_nlpsol_s": self.t_nlpsol,
            "t_construct_s": self.t_build + self.t_nlpsol,
        }
        for key in ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l"):
            if f"t_wall_{key}" in st:
                out[f"t_wall_{key}"] = float(st[f"t_wall_{key}"])
        if args.trajectory:
            np.savez(args.trajectory, x=xs_opt, u=us_opt)
        return out


def solve(args):
    out = Peer(args).solve()
    line = json.dumps(out)
    print(line)
    if args.json:
        with open(args.json, "w") as f:
            f.write(line + "\n")
    return 0 if out["success"] else 1


def serve(args):
    """Construct once, then one solve per line `solve` on stdin, one JSON line each on
    stdout (bench.py's persistent peers); `quit` or end of input stops."""
    peer = Peer(args)
    print(json.dumps({"ready": True, "t_construct_s": peer.t_build + peer.t_nlpsol}),
          flush=True)
    for line in sys.stdin:
        cmd = line.strip()
        if cmd == "quit":
            break
        if cmd == "solve":
            c0 = time.process_time()
            out = peer.solve()
            out["cpu_s"] = time.process_time() - c0
            print(json.dumps(out), flush=True)
    return 0


# ---------------------------------------------------------------------------------------
# Verification against the Rust binary


class Check:
    def __init__(self):
        self.failed = []

    def __call__(self, name, err, tol):
        ok = err <= tol
        print(f"  {'ok  ' if ok else 'FAIL'} {name}: {err:.3e} (tolerance {tol:.0e})")
        if not ok:
            self.failed.append(name)


def default_wip():
    here = os.path.abspath(os.path.join(HERE, "..", ".."))
    return os.path.join(here, "target", "release", "wip")


def read_csv(path):
    with open(path) as f:
        lines = [ln for ln in f if ln.strip() and not ln.startswith("#")]
    header = lines[0].strip().split(",")
    data = np.array([[float(v) for v in ln.strip().split(",")] for ln in lines[1:]])
    return header, data


def verify(args):
    p = load_params(args.params)
    wip = args.wip or default_wip()
    model = Model(p)
    check = Check()
    print("CasADi model against the Rust model")

    # 1. The continuous model against the reference vectors kept beside the Rust tests.
    ref = os.path.join(HERE, "..", "..", "robots", "tests", "data", "reference-vectors.json")
    if os.path.exists(ref) and not args.params:
        with open(ref) as f:
            vecs = json.load(f)["vectors"]
        worst = 0.0
        for v in vecs:
            got = np.array(model.reduced_rate(v["X"], v["u"])).ravel()
            want = np.array(v["Xdot"])
            worst = max(worst, np.max(np.abs(got - want)) / max(1.0, np.max(np.abs(want))))
        check(f"continuous model vs reference-vectors.json ({len(vecs)} states)", worst, 1e-10)

    # 2. RK steps against `wip simulate --integrator rkN`: a tilted, moving, turning start
    #    and voltages that vary every step. The explicit methods are unstable for the stiff
    #    current at the planner's 5 ms (`wip simulate` refuses: a factor |1 − h R_m/L_m| =
    #    17.75 per step), so the simulation runs at --sim-step (default 0.25 ms); the step
    #    map is x + h·f(x, u) for RK1, so agreement of the steps is agreement of f.
    h = args.sim_step
    nsteps = int(round(args.sim_time / h))
    t = np.arange(nsteps + 1) * h
    uR = 3.0 * np.sin(2 * math.pi * 0.7 * t) + 0.5
    uL = 2.5 * np.cos(2 * math.pi * 1.3 * t) - 0.3
    X0 = [0.3, -0.2, 0.4, 0.05, -0.3, 0.2, 0.8, 0.1, -0.05]
    for method in args.sim_integrators:
        with tempfile.TemporaryDirectory() as tmp:
            inputs = os.path.join(tmp, "inputs.csv")
            with open(inputs, "w") as f:
                f.write("t,uR,uL\n")
                for k in range(nsteps + 1):
                    f.write(f"{float(t[k])!r},{float(uR[k])!r},{float(uL[k])!r}\n")
            outdir = os.path.join(tmp, "sim")
            cmd = [wip, "simulate", "--integrator", method, "--step", repr(h), "--x0",
                   ",".join(repr(v) for v in X0), "--inputs", inputs, "--out", outdir]
            if args.params:
                cmd += ["--params", args.params]
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            header, data = read_csv(os.path.join(outdir, "trajectory.csv"))
        cols = [header.index(c) for c in
                ("x", "y", "theta", "alpha", "v_alpha", "v_d", "v_theta", "iR", "iL")]
        Xs = data[:, cols]
        F = model.step(h, method)
        # One step from each of the Rust states: the dynamics alone, no error growth.
        worst_step = 0.0
        for k in range(nsteps):
            xk = full_from_reduced(p, Xs[k])
            nxt = reduced_from_full(p, np.array(F(xk, [uR[k], uL[k]])).ravel())
            scale = np.maximum(1.0, np.abs(Xs[k + 1]))
            worst_step = max(worst_step, np.max(np.abs(nxt - Xs[k + 1]) / scale))
        check(f"{method} step vs wip simulate, {nsteps} steps of {h} s, each from the "
              f"Rust state", worst_step, 1e-12)
        # The whole trajectory from X0 (the fall, 7.4/s, amplifies round-off).
        x = full_from_reduced(p, np.array(X0))
        worst_traj = 0.0
        for k in range(nsteps):
            x = np.array(F(x, [uR[k], uL[k]])).ravel()
            got = reduced_from_full(p, x)
            worst_traj = max(worst_traj, np.max(np.abs(got - Xs[k + 1])
                                                / np.maximum(1.0, np.abs(Xs[k + 1]))))
        check(f"{method} trajectory vs wip simulate over {args.sim_time} s", worst_traj, 1e-10)
    h = args.step

    # 3. The optimum against `wip plan NAME --integrator rk1`.
    if not args.skip_plan:
        for name in args.problems:
            print(f"optimum of {name} (RK1, h = {h}) against wip plan")
            if args.summary and len(args.problems) == 1:
                with open(args.summary) as f:
                    ours = json.load(f)
            else:
                with tempfile.TemporaryDirectory() as tmp:
                    cmd = [wip, "plan", name, "--integrator", "rk1", "--step", repr(h),
                           "--quiet", "--out", tmp]
                    if args.params:
                        cmd += ["--params", args.params]
                    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
                    with open(os.path.join(tmp, "summary.json")) as f:
                        ours = json.load(f)
            with tempfile.TemporaryDirectory() as tmp:
                out = os.path.join(tmp, "peer.json")
                cmd = [sys.executable, os.path.abspath(__file__), "solve", "--problem", name,
                       "--solver", args.solver, "--step", repr(h), "--json", out]
                if args.params:
                    cmd += ["--params", args.params]
                subprocess.run(cmd, stdout=subprocess.DEVNULL)
                with open(out) as f:
                    peer = json.load(f)
            print(f"  wip plan: {ours['status']}, {ours['iterations']} iterations, "
                  f"J = {ours['objective']:.10f}")
            print(f"  {args.solver}: {peer['status']}, {peer['iterations']} iterations, "
                  f"J = {peer['objective']:.10f}, max violation {peer['max_violation']:.1e}")
            check(f"{name}: {args.solver} solved", 0.0 if peer["success"] else 1.0, 0.0)
            rel = abs(peer["objective"] - ours["objective"]) / abs(ours["objective"])
            check(f"{name}: objective, relative difference", rel, 1e-6)

    if check.failed:
        print(f"VERIFY FAILED: {', '.join(check.failed)}")
        return 1
    print("verify: all checks passed")
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    def solve_arguments(s):
        s.add_argument("--problem", default="eight", choices=["eight", "zigzag"])
        s.add_argument("--solver", default="ipopt", choices=["ipopt", "fatrop"])
        s.add_argument("--integrator", default="rk1", choices=["rk1", "rk2", "rk4"])
        s.add_argument("--step", type=float, default=0.005,
                       help="time step h in s (the scale series: 0.02 0.01 0.005 0.0025 "
                            "0.00125; RK1 needs the small ones, see README)")
        s.add_argument("--start", default="polyline", choices=["polyline", "linear"],
                       help="initial guess: the planner's polyline start (default) or a "
                            "crude piecewise-linear one")
        s.add_argument("--rate-form", default="rate", choices=["rate", "diff"],
                       help="rate limit as (u_k-u_{k-1})/h in [-2,2] (default, as the "
                            "planner) or u_k-u_{k-1} in [-2h,2h]")
        s.add_argument("--structure", default="auto", choices=["auto", "manual"],
                       help="FATROP: detect the stage structure, or pass it (N, nx, nu, ng)")
        s.add_argument("--tol", type=float, default=1e-6)
        s.add_argument("--max-iter", type=int, default=1000)
        s.add_argument("--no-jit", action="store_true", help="no C code generation")
        s.add_argument("--params", help="JSON parameter file (docs/formats.md)")
        s.add_argument("--trajectory", help="write the optimum (x, u) to this .npz file")
        s.add_argument("--verbose", action="store_true", help="the solver's iteration log")

    s = sub.add_parser("solve", help="one solve; a JSON line on stdout")
    solve_arguments(s)
    s.add_argument("--json", help="also write the result line to this file")
    s = sub.add_parser("serve", help="construct once, solve on each 'solve' line of stdin")
    solve_arguments(s)
    v = sub.add_parser("verify", help="check the model and the optimum against the Rust binary")
    v.add_argument("--wip", help="path of the wip binary (default: target/release/wip)")
    v.add_argument("--step", type=float, default=0.005)
    v.add_argument("--sim-time", type=float, default=1.0,
                   help="length of the simulated comparison, s")
    v.add_argument("--sim-step", type=float, default=2.5e-4,
                   help="step of the simulated comparison (explicit RK is unstable for the "
                        "current above 0.54 ms)")
    v.add_argument("--sim-integrators", nargs="+", default=["rk1", "rk4"],
                   choices=["rk1", "rk2", "rk4"])
    v.add_argument("--problems", nargs="+", default=["eight"], choices=["eight", "zigzag"])
    v.add_argument("--solver", default="ipopt", choices=["ipopt", "fatrop"],
                   help="the solver whose optimum is compared (default ipopt: FATROP's "
                        "CasADi interface takes minutes to construct at N = 4235)")
    v.add_argument("--summary", help="a summary.json of `wip plan NAME --integrator rk1` "
                                     "to compare with instead of running the plan")
    v.add_argument("--skip-plan", action="store_true", help="only the model checks")
    v.add_argument("--params", help="JSON parameter file (docs/formats.md)")
    a = ap.parse_args()
    if a.cmd == "solve":
        return solve(a)
    if a.cmd == "serve":
        return serve(a)
    return verify(a)


if __name__ == "__main__":
    sys.exit(main())
