"""Plan the paper's figure eight, track it in closed loop, and plot the path, the voltages
and the tracking error.

    python python/examples/plan_track_eight.py [OUT_DIR]

Writes OUT_DIR/eight_tracking.png (default OUT_DIR: the current folder)."""

import os
import sys

import matplotlib

matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
import matplotlib.pyplot as plt  # noqa: E402

import dmech  # noqa: E402

out = sys.argv[1] if len(sys.argv) > 1 else "."
plan = dmech.wip.plan("eight")
print(f"planned: J = {plan.objective:.6f}, {plan.iterations} iterations, {plan.solve_time_s:.2f} s")
run = dmech.wip.track(plan, controller="lq", seed=1)
print(f"tracked: position error max {1e3 * run.position_error_max_m:.2f} mm, "
      f"rms {1e3 * run.position_error_rms_m:.2f} mm, fell: {run.fell}")

c = run.columns
fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
ax[0].plot(plan.column("x"), plan.column("y"), "k--", label="plan")
ax[0].plot(c["x"], c["y"], label="closed loop")
ax[0].plot(*plan.waypoints.T, "o", label="waypoints")
ax[0].set(xlabel="x [m]", ylabel="y [m]", title="path", aspect="equal")
ax[0].legend()
ax[1].plot(c["t"], c["uR"], label="uR applied")
ax[1].plot(c["t"], c["uL"], label="uL applied")
ax[1].plot(plan.t, plan.column("uR"), "k:", lw=0.8, label="uR planned")
ax[1].set(xlabel="t [s]", ylabel="voltage [V]", title="motor voltages")
ax[1].legend()
ax[2].plot(c["t"], 1e3 * run.position_error())
ax[2].set(xlabel="t [s]", ylabel="position error [mm]", title="tracking error (LQ)")
fig.tight_layout()
path = os.path.join(out, "eight_tracking.png")
fig.savefig(path, dpi=90)
print(f"wrote {path}")
