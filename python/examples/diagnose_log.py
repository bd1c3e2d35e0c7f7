"""Generate a log of the robot with a hidden input delay, diagnose it, and plot the
residuals per reading before and after.

    python python/examples/diagnose_log.py [OUT_DIR]

Writes OUT_DIR/diagnosis_residuals.png (default OUT_DIR: the current folder)."""

import os
import sys

import matplotlib

matplotlib.use(os.environ.get("MPLBACKEND", "Agg"))
import matplotlib.pyplot as plt  # noqa: E402

import numpy as np  # noqa: E402

import dmech  # noqa: E402

out = sys.argv[1] if len(sys.argv) > 1 else "."
log = dmech.wip.generate("input_delay", seed=2, duration=10)
print("hidden:", log.truth["effects"])
frame = log.to_pandas()  # any DataFrame with the log's columns will do
d = dmech.wip.diagnose(frame, threads=2)
print(f"cause: {d.cause}; error {d.error_before:.3f} -> {d.error_after:.3f} (1 = noise floor)")
for cause in d.causes:
    for k, v in cause.parameters.items():
        print(f"  {k} = {v:.6e} ± {cause.uncertainty[k]:.1e}")

r = d.residuals
pairs = [k[: -len("_before")] for k in r if k.endswith("_before")]
fig, axes = plt.subplots(len(pairs), 1, figsize=(10, 1.8 * len(pairs)), sharex=True, squeeze=False)
for ax, name in zip(axes[:, 0], pairs):
    seen = np.isfinite(r[name + "_before"])  # the pose is read at 50 Hz, not every row
    style = dict(lw=0.6) if seen.mean() > 0.5 else dict(lw=0, marker=".", ms=2)
    ax.plot(r["t"][seen], r[name + "_before"][seen], label="nominal model", **style)
    ax.plot(r["t"][seen], r[name + "_after"][seen], label=f"with {d.cause}", **style)
    ax.set_ylabel(name, rotation=0, ha="right")
axes[0, 0].legend(loc="upper right")
axes[-1, 0].set_xlabel("t [s]")
fig.suptitle("prediction − reading, per channel (SI units)")
fig.tight_layout()
path = os.path.join(out, "diagnosis_residuals.png")
fig.savefig(path, dpi=80)
print(f"wrote {path}")
