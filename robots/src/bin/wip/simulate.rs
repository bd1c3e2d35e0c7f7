//! `wip simulate`: open-loop simulation from a state with zero-order-hold voltages.

use crate::common::{load_params, positive_count, sim_step, Failure};
use dmech::Integrator;
use robots::cli::integrator_parser;
use robots::io::{read_inputs, OutputSet};
use robots::say;
use robots::wip::simulate::trajectory_csv;
use robots::wip::simulate::{check_simulation, simulate};
use robots::wip::{ReducedState, Wip};
use std::path::PathBuf;

/// Simulate the WIP open loop from a state with given voltages.
///
/// Starts from the reduced state --x0 (SI units, radians) and applies the voltages of the
/// inputs file (columns t,uR,uL; zero-order hold; the first row at t = 0, the last row's t
/// is the end of the horizon and must be a whole number of steps). Writes
/// DIR/trajectory.csv (docs/formats.md).
#[derive(clap::Args)]
pub struct SimulateArgs {
    /// Initial state "x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL"
    #[arg(long, value_name = "STATE", allow_hyphen_values = true)]
    x0: String,
    /// Voltages: CSV with columns t,uR,uL
    #[arg(long, value_name = "FILE.csv")]
    inputs: PathBuf,
    /// Time-stepping scheme
    #[arg(long, default_value = "first-order", value_parser = integrator_parser(&Integrator::ALL))]
    integrator: Integrator,
    /// Time step in seconds, in (0, 1]
    #[arg(long = "step", alias = "h", value_name = "SECONDS", default_value = "0.005", allow_negative_numbers = true, value_parser = sim_step)]
    step: f64,
    /// JSON parameter file (docs/formats.md), e.g. a diagnosis's params_refit.json
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Output directory
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Largest number of steps accepted (each row of trajectory.csv takes about 300 bytes)
    #[arg(long, value_name = "N", default_value = "2000000", value_parser = positive_count)]
    max_steps: usize,
    /// Largest |voltage| accepted in the inputs file; the model has no saturation, and the
    /// motors of the WIP are driven at 5 V
    #[arg(long, value_name = "VOLTS", default_value = "24", value_parser = crate::common::positive_number)]
    max_voltage: f64,
}

pub fn run(a: SimulateArgs) -> Result<(), Failure> {
    let h = a.step;
    let x = parse_state(&a.x0)?;
    let params = load_params(a.params.as_deref())?;
    // Every row lies on the step grid, so the file holds at most one row per step.
    let sched = read_inputs(
        &a.inputs,
        a.max_steps.saturating_add(1),
        " (one row a step at most: raise it with --max-steps)",
    )?;
    let what = format!("inputs file {}", a.inputs.display());
    let wip = Wip::new(params);
    let integrator = a.integrator;
    let n = check_simulation(
        &wip,
        integrator,
        h,
        &x,
        &sched,
        &what,
        a.max_steps,
        a.max_voltage,
    )
    .map_err(|e| Failure::Run(e.to_string()))?;
    let mut files = OutputSet::create(&a.out)?;
    let t0 = std::time::Instant::now();
    let traj = simulate(&wip, integrator, h, &x, &sched, n)?;
    let elapsed = t0.elapsed().as_secs_f64();
    files.write("trajectory.csv", trajectory_csv(&traj)?.as_bytes())?;
    files.commit()?;
    let xf = traj.x.last().expect("at least one state");
    say!(
        "simulated {n} steps of {h} s with {} in {elapsed:.3} s; final state x={:.6} y={:.6} theta={:.6} alpha={:.6} v_d={:.6} v_theta={:.6} iR={:.6} iL={:.6}",
        integrator.name(),
        xf[0], xf[1], xf[2], xf[3], xf[5], xf[6], xf[7], xf[8]
    );
    say!("wrote {}", a.out.join("trajectory.csv").display());
    Ok(())
}

fn parse_state(text: &str) -> Result<ReducedState, Failure> {
    let fields: Vec<&str> = text.split(',').collect();
    if fields.len() != 9 {
        return Err(Failure::Run(format!(
            "--x0 needs 9 comma-separated numbers (x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL), got {}",
            fields.len()
        )));
    }
    let mut x = ReducedState::zeros();
    for (i, f) in fields.iter().enumerate() {
        x[i] = f
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                format!(
                    "--x0 component {} ('{}') is not a finite number",
                    i + 1,
                    f.trim()
                )
            })?;
    }
    Ok(x)
}
