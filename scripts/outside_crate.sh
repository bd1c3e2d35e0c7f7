#!/usr/bin/env bash
# A crate outside the workspace that tracks a plan of its own robot through
# dmech_ocp::tracking (LQ and the constrained MPC), depending on dmech-lie, dmech and
# dmech-ocp by path: it is created in a temporary directory, built and run, and
# `cargo tree` must show none of clap, csv or robots among its dependencies.
# Exits non-zero if the build, the run or the check fails. Usage: scripts/outside_crate.sh
# (KEEP=1 keeps the temporary directory; CARGO_TARGET_DIR is honoured.)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
dir="$(mktemp -d)"
if [ "${KEEP:-0}" = 1 ]; then echo "crate in $dir"; else trap 'rm -rf "$dir"' EXIT; fi
nalgebra="$(sed -n 's/^nalgebra = "\(.*\)"$/\1/p' "$root/Cargo.toml")"
mkdir -p "$dir/src"
cat > "$dir/Cargo.toml" <<TOML
[package]
name = "outside"
version = "0.1.0"
edition = "2021"
publish = false

[dependencies]
dmech-lie = { path = "$root/dmech-lie" }
dmech = { path = "$root/dmech" }
dmech-ocp = { path = "$root/dmech-ocp" }
nalgebra = "$nalgebra"

# A path dependency does not inherit the workspace's profiles (docs/add-a-robot.md).
[profile.dev]
opt-level = 2
[profile.dev.package."*"]
opt-level = 3

[workspace]
TOML
# The same versions as the workspace's, so that the build needs no registry lookup.
cp "$root/Cargo.lock" "$dir/Cargo.lock"
cat > "$dir/src/main.rs" <<'RUST'
//! A kart of our own (bicycle model, steering and drive torques) parked by one planning
//! call, then tracked on a 10 % heavier kart started 2 cm to the side: open loop, LQ and
//! the constrained MPC of dmech_ocp::tracking.
use dmech::{Discretisation, Lift, PrincipalKinematicSystem};
use dmech_lie::{Real, Se2};
use dmech_ocp::qp::QpSettings;
use dmech_ocp::solver::Status;
use dmech_ocp::toolkit::plan::{plan, PlanSettings, PlanStart};
use dmech_ocp::tracking::{
    linearise_along, lq_gains, track, track_by, Mpc, MpcSettings, TrackingWeights,
};
use dmech_ocp::transcription::{
    Condition, PlanningProblem, Quantity, Stage, StartState, VarIntTranscription,
};
use nalgebra::{Matrix3x2, SMatrix, SVector, Vector2, Vector3};

struct Kart { m: f64, b: f64, j: f64, wheelbase: f64, r: f64, i_w: f64, i_s: f64 }

impl PrincipalKinematicSystem<3, 2, 2> for Kart {
    type Param = f64;
    type Group<T: Real> = Se2<T>;
    fn reduced_lagrangian<T: Lift<f64>>(&self, _s: &SVector<T, 2>, v: &SVector<T, 2>, xi: &SVector<T, 3>) -> T {
        let lateral = xi[1] + xi[2] * self.b;
        let steer = xi[2] + v[0];
        (xi[0] * xi[0] + lateral * lateral) * (0.5 * self.m) + xi[2] * xi[2] * (0.5 * self.j)
            + steer * steer * (0.5 * self.i_s) + v[1] * v[1] * (0.5 * self.i_w)
    }
    fn connection<T: Lift<f64>>(&self, s: &SVector<T, 2>) -> SMatrix<T, 3, 2> {
        let z = T::zero();
        let yaw = s[0].tan() * (self.r / self.wheelbase);
        Matrix3x2::new(z, T::from(-self.r), z, z, z, -yaw)
    }
    fn forcing<T: Lift<f64>>(&self, _s: &SVector<T, 2>, v: &SVector<T, 2>, u: &SVector<T, 2>) -> SVector<T, 2> {
        Vector2::new(u[0] - v[0] * 0.02, u[1] - v[1] * 1e-3)
    }
}

const TORQUE: [f64; 2] = [0.05, 0.035];

/// Rest to rest at `end` in `n` steps, torques within their bounds.
struct Park { n: usize, end: [f64; 3] }

impl PlanningProblem<3, 2, 2, 3> for Park {
    fn horizon(&self) -> usize { self.n }
    fn start(&self) -> StartState<3, 2, 2> { StartState::at_rest(SVector::zeros(), SVector::zeros()) }
    fn cost<T: Real>(&self, _k: usize, st: &Stage<T, 3, 2, 2>) -> T {
        let (a, b) = (st.input[0] * (1.0 / TORQUE[0]), st.input[1] * (1.0 / TORQUE[1]));
        (a * a + b * b) * 0.5
    }
    fn constraints<T: Real>(&self, _k: usize, st: &Stage<T, 3, 2, 2>) -> SVector<T, 3> {
        Vector3::new(st.input[0], st.input[1], st.shape[0])
    }
    fn bounds(&self, _k: usize) -> (SVector<f64, 3>, SVector<f64, 3>) {
        let hi = Vector3::new(TORQUE[0], TORQUE[1], 0.6);
        (-hi, hi)
    }
    fn conditions(&self) -> Vec<Condition> {
        let at_end = |quantity, value| Condition { stage: self.n, quantity, value };
        let mut c: Vec<Condition> = (0..3).map(|i| at_end(Quantity::Pose(i), self.end[i])).collect();
        c.extend((0..2).map(|i| at_end(Quantity::Velocity(i), 0.0)));
        c
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let kart = Kart { m: 2.0, b: 0.1, j: 0.02, wheelbase: 0.25, r: 0.05, i_w: 5e-4, i_s: 1e-3 };
    let end = [-0.8, -0.2, 0.0];
    let pose = |tau: f64| {
        let f = tau * tau * (3.0 - 2.0 * tau);
        let (q, dq) = (f * f * f * (10.0 - 15.0 * f + 6.0 * f * f), 30.0 * (f * (1.0 - f)).powi(2));
        Se2::new(end[0] * f, end[1] * q, (end[1] * dq / end[0]).atan())
    };
    let path = |n: usize| (0..=n).map(|k| pose(k as f64 / n as f64)).collect::<Vec<_>>();
    let park_at = |h: f64| Some(Park { n: (6.0 / h).round() as usize, end });
    let (h, scheme) = (0.02, Discretisation::Midpoint);
    let start = PlanStart::Path { path: &path, regularisation: Vector2::new(1e-4, 1e-6) };
    let p = plan(&kart, park_at, &PlanSettings::new(h, scheme), &start)?;
    if p.status != Status::Solved {
        return Err(format!("the plan was not solved: {:?}", p.status).into());
    }
    let tr = VarIntTranscription::new(&kart, park_at(h).unwrap(), h, scheme);
    let (px, pw) = tr.states_of::<3>(&p.trajectory);
    let lin = linearise_along(&tr, &px, &pw)?;
    let mut q = SMatrix::<f64, 9, 9>::from_diagonal_element(1e-2);
    (q[(0, 0)], q[(1, 1)], q[(2, 2)]) = (1e4, 1e4, 400.0);
    let r = SMatrix::<f64, 2, 2>::from_diagonal(&Vector2::new(400.0, 1.0 / (TORQUE[1] * TORQUE[1])));
    let gains = lq_gains(&lin, &q, &(q * 10.0), &r)?;
    let weights = TrackingWeights { state: q, terminal: q * 10.0, input: r };
    let limit = Vector2::new(2.0 * TORQUE[0], 2.0 * TORQUE[1]);
    let settings = MpcSettings { horizon: 10, lower: -limit, upper: limit, qp: QpSettings::default() };
    let inputs = pw.iter().map(|w| w.fixed_rows::<2>(2).into_owned()).collect();
    let mut mpc = Mpc::new(lin, inputs, &weights, settings)?;

    let heavier = Kart { m: 2.2, j: 0.022, ..kart };
    let plant = VarIntTranscription::new(&heavier, park_at(h).unwrap(), h, scheme);
    let mut x0 = px[0];
    x0[1] += 0.02;
    let n = pw.len();
    let miss = |xs: &[SVector<f64, 9>]| (xs[n][0] - end[0]).hypot(xs[n][1] - end[1]);
    let open_loop = miss(&track(&plant, &x0, &px, &pw, None)?);
    let lq = miss(&track(&plant, &x0, &px, &pw, Some(&gains))?);
    let (mut solved, mut cpu) = (0, Vec::new());
    let mpc_run = track_by(&plant, &x0, &pw, |k, x| {
        let m = mpc.input(k, &(x - px[k])).expect("k is a stage of the plan");
        solved += usize::from(m.solved());
        cpu.push(m.cpu_s);
        m.input
    })?;
    let mpc_miss = miss(&mpc_run);
    cpu.sort_by(f64::total_cmp);
    println!(
        "end position error: open loop {:.1} mm, LQ {:.2} mm, MPC {:.2} mm ({solved} of {n} QPs solved, median {:.3} ms CPU)",
        1e3 * open_loop, 1e3 * lq, 1e3 * mpc_miss, 1e3 * cpu[n / 2]
    );
    if !(lq < 0.1 * open_loop && mpc_miss < 0.1 * open_loop && solved == n) {
        return Err("the closed loops did not bring the kart in".into());
    }
    Ok(())
}
RUST
cd "$dir"
start=$(date +%s)
offline=--offline
cargo build --quiet $offline 2>/dev/null || { offline=; cargo build --quiet; }
built=$(date +%s)
echo "built in $((built - start)) s"
cargo run --quiet $offline
echo "ran in $(( $(date +%s) - built )) s"
tree="$(cargo tree $offline -e normal,build --prefix none)"
bad=0
for name in clap csv robots; do
    if grep -q "^$name v" <<<"$tree"; then echo "error: $name is among the dependencies" >&2; bad=1; fi
done
[ "$bad" = 0 ] || exit 1
echo "cargo tree: $(sort -u <<<"$tree" | wc -l) crates, none of clap, csv, robots"
