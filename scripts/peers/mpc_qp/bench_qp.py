#!/usr/bin/env python3
"""The WIP MPC's QPs of a real run, solved by DAQP, PIQP, OSQP, ProxQP and clarabel from
PyPI and by dmech_ocp::qp (through `mpc_qps time`), one machine, one run (README.md).

Reads a file of QPs in dmech_ocp::qp's text form; gives every peer the same QP, written
out in the form it takes (sparse stage-wise with the states as variables, or condensed:
states eliminated through the dynamics); times setup + solve, cold, `--rounds` times per
QP (median per QP, then median, p99 and largest over the QPs); checks each peer's
`δu_0` against ours. Writes a JSON of everything and prints a markdown table.
"""
import argparse
import datetime
import importlib.metadata
import json
import math
import os
import platform
import subprocess
import time

import numpy as np
import scipy.sparse as sp

INF = math.inf


# ---------------------------------------------------------------- the text form
def read_qps(path):
    """Each QP as a dict of numpy arrays (the text form: dmech-ocp/src/qp/text.rs)."""
    tokens = open(path).read().split()
    pos = 0

    def take(n):
        nonlocal pos
        v = np.array([float(t) for t in tokens[pos:pos + n]])
        pos += n
        return v

    def label(name):
        nonlocal pos
        assert tokens[pos] == name, (pos, tokens[pos], name)
        pos += 1

    def rows(nx, nu, nc, with_e):
        label("D"); d = take(nc * nx).reshape(nc, nx)
        e = np.zeros((nc, nu))
        if with_e:
            label("E"); e = take(nc * nu).reshape(nc, nu)
        label("lo"); lo = take(nc)
        label("hi"); hi = take(nc)
        label("soft"); soft = take(2 * nc).reshape(nc, 2)
        return dict(d=d, e=e, lo=lo, hi=hi, soft=soft)

    qps = []
    while pos < len(tokens):
        label("stage_qp")
        nx, nu, nc, n = (int(t) for t in tokens[pos:pos + 4]); pos += 4
        label("x0"); x0 = take(nx)
        stages = []
        for k in range(n):
            label("stage"); assert int(tokens[pos]) == k; pos += 1
            st = {}
            for name, shape in [("A", (nx, nx)), ("B", (nx, nu)), ("c", (nx,)), ("Q", (nx, nx)),
                                ("S", (nx, nu)), ("R", (nu, nu)), ("q", (nx,)), ("r", (nu,))]:
                label(name); st[name] = take(int(np.prod(shape))).reshape(shape)
            st.update(rows(nx, nu, nc, True))
            stages.append(st)
        label("terminal")
        term = {}
        label("Q"); term["Q"] = take(nx * nx).reshape(nx, nx)
        label("q"); term["q"] = take(nx)
        term.update(rows(nx, nu, nc, False))
        label("end")
        qps.append(dict(nx=nx, nu=nu, nc=nc, n=n, x0=x0, stages=stages, terminal=term))
    return qps


# ---------------------------------------------------------------- the forms
def soft_rows(qp):
    """(stage, row) of every soft row with a finite side: one violation variable each."""
    out = []
    for k in range(qp["n"] + 1):
        r = qp["stages"][k] if k < qp["n"] else qp["terminal"]
        for i in range(qp["nc"]):
            if not math.isnan(r["soft"][i, 0]) and (math.isfinite(r["lo"][i]) or math.isfinite(r["hi"][i])):
                out.append((k, i))
    return out


def stacked(qp):
    """The stage-wise blocks stacked over y = (x_0 … x_N, u_0 … u_{N−1}): the Hessian H,
    gradient g, the dynamics M y = m, the rows Z y (row values) with bounds and soft
    prices, and the violation variables."""
    nx, nu, nc, n = qp["nx"], qp["nu"], qp["nc"], qp["n"]
    ny = nx * (n + 1) + nu * n
    xi = lambda k: slice(nx * k, nx * (k + 1))
    ui = lambda k: slice(nx * (n + 1) + nu * k, nx * (n + 1) + nu * (k + 1))
    H = np.zeros((ny, ny)); g = np.zeros(ny)
    M = np.zeros((nx * n, ny)); m = np.zeros(nx * n)
    Z = np.zeros((nc * (n + 1), ny)); lo = np.zeros(nc * (n + 1)); hi = np.zeros(nc * (n + 1))
    for k, st in enumerate(qp["stages"]):
        H[xi(k), xi(k)] = st["Q"]; H[xi(k), ui(k)] = st["S"]; H[ui(k), xi(k)] = st["S"].T
        H[ui(k), ui(k)] = st["R"]; g[xi(k)] = st["q"]; g[ui(k)] = st["r"]
        rows = slice(nx * k, nx * (k + 1))
        M[rows, xi(k + 1)] = np.eye(nx); M[rows, xi(k)] = -st["A"]; M[rows, ui(k)] = -st["B"]
        m[rows] = st["c"]
        zr = slice(nc * k, nc * (k + 1))
        Z[zr, xi(k)] = st["d"]; Z[zr, ui(k)] = st["e"]; lo[zr] = st["lo"]; hi[zr] = st["hi"]
    t = qp["terminal"]
    H[xi(n), xi(n)] = t["Q"]; g[xi(n)] = t["q"]
    zr = slice(nc * n, nc * (n + 1))
    Z[zr, xi(n)] = t["d"]; lo[zr] = t["lo"]; hi[zr] = t["hi"]
    soft = soft_rows(qp)
    return dict(H=H, g=g, M=M, m=m, Z=Z, lo=lo, hi=hi, soft=soft, ny=ny, xi=xi, ui=ui)


def rows_with_violations(qp, s, Zv, nv_soft_offset):
    """General rows l ≤ C v ≤ u over v = (primal part, σ): a hard row two-sided; a soft row
    as `z − σ ≤ hi` and `z + σ ≥ lo` (one each); the bounds σ ≥ 0 apart."""
    nc = qp["nc"]
    soft_index = {ki: j for j, ki in enumerate(s["soft"])}
    C, l, u = [], [], []
    nvar = Zv.shape[1] + len(s["soft"])
    for r in range(Zv.shape[0]):
        k, i = divmod(r, nc)
        lo, hi = s["lo"][r], s["hi"][r]
        if not (math.isfinite(lo) or math.isfinite(hi)):
            continue
        row = np.zeros(nvar); row[:Zv.shape[1]] = Zv[r]
        j = soft_index.get((k, i))
        if j is None:
            C.append(row); l.append(lo); u.append(hi)
            continue
        if math.isfinite(hi):
            a = row.copy(); a[nv_soft_offset + j] = -1.0
            C.append(a); l.append(-INF); u.append(hi)
        if math.isfinite(lo):
            a = row.copy(); a[nv_soft_offset + j] = 1.0
            C.append(a); l.append(lo); u.append(INF)
    return np.array(C), np.array(l), np.array(u)


def soft_prices(qp, s):
    l1, l2 = [], []
    for (k, i) in s["soft"]:
        r = qp["stages"][k] if k < qp["n"] else qp["terminal"]
        l1.append(r["soft"][i, 0]); l2.append(r["soft"][i, 1])
    return np.array(l1), np.array(l2)


def condensed(qp):
    """min ½ vᵀPv + fᵀv, l ≤ C v ≤ u, σ ≥ 0, v = (u_0 … u_{N−1}, σ): the states
    eliminated, x = T_x x_0 + T_u U + t_c (the dynamics), x_0 given."""
    s = stacked(qp)
    nx, nu, n = qp["nx"], qp["nu"], qp["n"]
    # x_stack = X0 + T U
    X0 = np.zeros(nx * (n + 1)); T = np.zeros((nx * (n + 1), nu * n))
    X0[:nx] = qp["x0"]
    for k, st in enumerate(qp["stages"]):
        X0[nx * (k + 1):nx * (k + 2)] = st["A"] @ X0[nx * k:nx * (k + 1)] + st["c"]
        T[nx * (k + 1):nx * (k + 2)] = st["A"] @ T[nx * k:nx * (k + 1)]
        T[nx * (k + 1):nx * (k + 2), nu * k:nu * (k + 1)] += st["B"]
    nxs = nx * (n + 1)
    L = np.vstack([T, np.eye(nu * n)])              # y = L U + y0
    y0 = np.concatenate([X0, np.zeros(nu * n)])
    Hu = L.T @ s["H"] @ L
    fu = L.T @ (s["H"] @ y0 + s["g"])
    const = 0.5 * y0 @ s["H"] @ y0 + s["g"] @ y0
    l1, l2 = soft_prices(qp, s)
    ns = len(l1); nv = nu * n + ns
    P = np.zeros((nv, nv)); P[:nu * n, :nu * n] = Hu; P[nu * n:, nu * n:] = np.diag(l2)
    f = np.concatenate([fu, l1])
    Zu = s["Z"] @ L; z0 = s["Z"] @ y0
    s2 = dict(s, lo=s["lo"] - z0, hi=s["hi"] - z0)
    C, l, u = rows_with_violations(qp, s2, Zu, nu * n)
    P = 0.5 * (P + P.T)
    return dict(P=P, f=f, C=C, l=l, u=u, ns=ns, nu_total=nu * n, const=const, nu=nu)


def sparse_form(qp):
    """min ½ vᵀPv + fᵀv, M v = m, l ≤ C v ≤ u, σ ≥ 0, v = (x_1 … x_N, u_0 … u_{N−1}, σ)."""
    s = stacked(qp)
    nx = qp["nx"]
    keep = np.arange(nx, s["ny"])                   # drop x_0 (given)
    x0 = qp["x0"]
    y0 = np.zeros(s["ny"]); y0[:nx] = x0
    H = s["H"][np.ix_(keep, keep)]
    g = (s["g"] + s["H"] @ y0)[keep]
    const = 0.5 * y0 @ s["H"] @ y0 + s["g"] @ y0
    M = s["M"][:, keep]; m = s["m"] - s["M"] @ y0
    Z = s["Z"][:, keep]; z0 = s["Z"] @ y0
    s2 = dict(s, lo=s["lo"] - z0, hi=s["hi"] - z0)
    np_ = len(keep)
    C, l, u = rows_with_violations(qp, s2, Z, np_)
    l1, l2 = soft_prices(qp, s)
    ns = len(l1)
    P = sp.block_diag([sp.csc_matrix(H), sp.diags(l2)], format="csc")
    f = np.concatenate([g, l1])
    Meq = sp.hstack([sp.csc_matrix(M), sp.csc_matrix((M.shape[0], ns))], format="csc")
    return dict(P=P, f=f, M=Meq, m=m, C=sp.csc_matrix(C), l=l, u=u, ns=ns, np=np_,
                u0=slice(nx * qp["n"], nx * qp["n"] + qp["nu"]), const=const)


# ---------------------------------------------------------------- the peers
def peer_daqp(qp, form):
    import daqp
    c = form
    nv = c["P"].shape[0]
    # Simple bounds first (σ ≥ 0; the inputs free), then the general rows.
    bl = np.concatenate([np.full(c["nu_total"], -1e30), np.zeros(c["ns"]), np.where(np.isfinite(c["l"]), c["l"], -1e30)])
    bu = np.concatenate([np.full(nv, 1e30), np.where(np.isfinite(c["u"]), c["u"], 1e30)])
    sense = np.zeros(len(bu), dtype=np.int32)
    t0 = time.perf_counter()
    x, fval, flag, info = daqp.solve(c["P"], c["f"], c["C"], bu, bl, sense, eps_prox=-1)
    wall = time.perf_counter() - t0
    return dict(ok=flag >= 1, u0=x[:qp["nu"]], time=info["setup_time"] + info["solve_time"], wall=wall)


def peer_proxqp(qp, form):
    import proxsuite
    c = form
    nv = c["P"].shape[0]
    C = np.vstack([c["C"], np.eye(nv)[c["nu_total"]:]])
    l = np.concatenate([c["l"], np.zeros(c["ns"])]); u = np.concatenate([c["u"], np.full(c["ns"], 1e20)])
    l = np.where(np.isfinite(l), l, -1e20); u = np.where(np.isfinite(u), u, 1e20)
    t0 = time.perf_counter()
    q = proxsuite.proxqp.dense.QP(nv, 0, C.shape[0])
    q.settings.compute_timings = True
    q.init(c["P"], c["f"], None, None, C, l, u)
    q.solve()
    wall = time.perf_counter() - t0
    info = q.results.info
    ok = info.status == proxsuite.proxqp.PROXQP_SOLVED
    return dict(ok=ok, u0=q.results.x[:qp["nu"]], time=1e-6 * (info.setup_time + info.solve_time), wall=wall)


def peer_piqp_dense(qp, form):
    import piqp
    c = form
    nv = c["P"].shape[0]
    xl = np.concatenate([np.full(c["nu_total"], -INF), np.zeros(c["ns"])])
    t0 = time.perf_counter()
    s = piqp.DenseSolver()
    s.settings.verbose = False
    s.settings.compute_timings = True
    s.setup(np.asfortranarray(c["P"]), c["f"], None, None, np.asfortranarray(c["C"]), c["l"], c["u"], xl, np.full(nv, INF))
    status = s.solve()
    wall = time.perf_counter() - t0
    return dict(ok=status == piqp.PIQP_SOLVED, u0=s.result.x[:qp["nu"]], time=s.result.info.run_time, wall=wall)


def peer_piqp_sparse(qp, form):
    import piqp
    c = form
    nv = c["P"].shape[0]
    xl = np.concatenate([np.full(c["np"], -INF), np.zeros(c["ns"])])
    t0 = time.perf_counter()
    s = piqp.SparseSolver()
    s.settings.verbose = False
    s.settings.compute_timings = True
    s.setup(sp.triu(c["P"], format="csc"), c["f"], c["M"], c["m"], c["C"], c["l"], c["u"], xl, np.full(nv, INF))
    status = s.solve()
    wall = time.perf_counter() - t0
    return dict(ok=status == piqp.PIQP_SOLVED, u0=s.result.x[c["u0"]], time=s.result.info.run_time, wall=wall)


def peer_osqp(qp, form):
    import osqp
    c = form
    nv = c["P"].shape[0]
    A = sp.vstack([c["M"], c["C"], sp.hstack([sp.csc_matrix((c["ns"], c["np"])), sp.eye(c["ns"])])], format="csc")
    l = np.concatenate([c["m"], c["l"], np.zeros(c["ns"])])
    u = np.concatenate([c["m"], c["u"], np.full(c["ns"], INF)])
    t0 = time.perf_counter()
    s = osqp.OSQP()
    s.setup(sp.triu(c["P"], format="csc"), c["f"], A, l, u, verbose=False)
    r = s.solve()
    wall = time.perf_counter() - t0
    ok = r.info.status_val == osqp.SolverStatus.OSQP_SOLVED if hasattr(osqp, "SolverStatus") else r.info.status == "solved"
    return dict(ok=bool(ok), u0=r.x[c["u0"]], time=r.info.run_time, wall=wall)


def peer_clarabel(qp, form):
    import clarabel
    c = form
    rows, b = [c["M"]], [c["m"]]
    fin_u = np.isfinite(c["u"]); fin_l = np.isfinite(c["l"])
    rows += [c["C"][fin_u], -c["C"][fin_l], sp.hstack([sp.csc_matrix((c["ns"], c["np"])), -sp.eye(c["ns"])])]
    b += [c["u"][fin_u], -c["l"][fin_l], np.zeros(c["ns"])]
    A = sp.vstack(rows, format="csc"); bb = np.concatenate(b)
    cones = [clarabel.ZeroConeT(c["M"].shape[0]), clarabel.NonnegativeConeT(A.shape[0] - c["M"].shape[0])]
    settings = clarabel.DefaultSettings(); settings.verbose = False; settings.presolve_enable = False
    t0 = time.perf_counter()
    s = clarabel.DefaultSolver(sp.triu(c["P"], format="csc"), c["f"], A, bb, cones, settings)
    sol = s.solve()
    wall = time.perf_counter() - t0
    return dict(ok=str(sol.status) == "Solved", u0=np.array(sol.x)[c["u0"]], time=sol.solve_time, wall=wall)


PEERS = [
    ("DAQP (dense, condensed)", "condensed", peer_daqp),
    ("PIQP (dense, condensed)", "condensed", peer_piqp_dense),
    ("PIQP (sparse)", "sparse", peer_piqp_sparse),
    ("ProxQP (dense, condensed)", "condensed", peer_proxqp),
    ("OSQP (sparse)", "sparse", peer_osqp),
    ("clarabel (sparse)", "sparse", peer_clarabel),
]


def summary(times):
    t = np.sort(np.asarray(times))
    return dict(median_us=1e6 * float(np.median(t)), p99_us=1e6 * float(np.quantile(t, 0.99)),
                max_us=1e6 * float(t[-1]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("qps", help="a file of QPs (mpc_qps dump)")
    ap.add_argument("--ours", required=True, help="the mpc_qps example binary")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", default="results.json")
    a = ap.parse_args()
    qps = read_qps(a.qps)
    forms = dict(condensed=[condensed(q) for q in qps], sparse=[sparse_form(q) for q in qps])
    started = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    ours = json.loads(subprocess.run([a.ours, "time", a.qps, "--rounds", str(a.rounds)],
                                     check=True, capture_output=True, text=True).stdout)
    u_ours = np.array(ours["cold"]["u0"])
    results = {"ours, cold": dict(summary(ours["cold"]["time_s"]), failures=int(sum(not s for s in ours["cold"]["solved"])),
                                  du0_max=0.0, reported="Instant around StageQp::new + solve"),
               "ours, warm (previous QP shifted)": dict(summary(ours["warm"]["time_s"]), failures=int(sum(not s for s in ours["warm"]["solved"])),
                                                        du0_max=float(np.abs(np.array(ours["warm"]["u0"]) - u_ours).max()),
                                                        reported="one round, consecutive QPs")}
    for name, form, fn in PEERS:
        per_qp, walls, fails, du = [], [], 0, 0.0
        for i, qp in enumerate(qps):
            runs = [fn(qp, forms[form][i]) for _ in range(a.rounds)]
            per_qp.append(float(np.median([r["time"] for r in runs])))
            walls.append(float(np.median([r["wall"] for r in runs])))
            r = runs[-1]
            if not r["ok"]:
                fails += 1
            else:
                du = max(du, float(np.abs(np.asarray(r["u0"]) - u_ours[i]).max()))
        results[name] = dict(summary(per_qp), failures=fails, du0_max=du,
                             wall_median_us=1e6 * float(np.median(walls)),
                             reported="the solver's own setup + solve time")
        print(f"{name}: done", flush=True)
    base = results["ours, cold"]["median_us"]
    for r in results.values():
        r["ratio_to_ours_cold"] = r["median_us"] / base
    info = dict(started=started, machine=platform.processor() or platform.machine(),
                cpu=open("/proc/cpuinfo").read().split("model name")[1].split("\n")[0].strip(": \t") if os.path.exists("/proc/cpuinfo") else "",
                affinity=sorted(os.sched_getaffinity(0)), qps=len(qps), file=os.path.basename(a.qps),
                rounds=a.rounds, load=os.getloadavg(),
                versions={p: importlib.metadata.version(p) for p in
                          ["daqp", "piqp", "osqp", "proxsuite", "clarabel", "numpy", "scipy"]})
    json.dump(dict(info=info, results=results), open(a.out, "w"), indent=1)
    print(f"\n{len(qps)} QPs, {a.rounds} rounds, {info['cpu']}, CPUs {info['affinity']}, load {info['load']}\n")
    print("| solver | median µs | p99 µs | max µs | × ours cold | failures | max |δu_0 − ours| (V) |")
    print("|---|---|---|---|---|---|---|")
    for name, r in results.items():
        print(f"| {name} | {r['median_us']:.1f} | {r['p99_us']:.1f} | {r['max_us']:.1f} | {r['ratio_to_ours_cold']:.2f} | {r['failures']} | {r['du0_max']:.1e} |")


if __name__ == "__main__":
    main()
