//! `wip`: plan, simulate and check the wheeled inverted pendulum.
//! Exit status: 0 success, 1 a failure explained in one line on stderr, 2 bad usage.

use lexopt::prelude::*;
use robots::io::{read_inputs, trajectory_csv, write_atomic};
use robots::wip::simulate::{simulate, Integrator};
use robots::wip::{ReducedState, Wip, WipParams};
use std::path::PathBuf;
use std::process::ExitCode;

const USAGE: &str = "\
usage: wip <subcommand> [options]

subcommands:
  simulate   open-loop simulation from a state with given voltages

Run `wip <subcommand> --help` for its options.";

const SIMULATE_HELP: &str = "\
usage: wip simulate --x0 \"x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL\" --inputs FILE.csv
                    [--integrator varint|rk1|rk2|rk4] [--h SECONDS] [--params FILE]
                    [--out DIR]

Simulates the WIP open loop from the reduced state --x0 (SI units, radians) with the
voltages of FILE.csv (columns t,uR,uL; zero-order hold; the first row at t = 0, the last
row's t is the end of the horizon). Writes DIR/trajectory.csv (default DIR: out).

  --integrator  varint (default: the variational integrator, right-point forcing),
                rk1, rk2 (explicit midpoint), rk4 on the continuous model
  --h           step in seconds (default 0.005)
  --params      JSON parameter file; any subset of the keys of model.md's table";

/// A failure: exit status and one line.
enum Failure {
    Usage(String),
    Run(String),
}

impl From<lexopt::Error> for Failure {
    fn from(e: lexopt::Error) -> Self {
        Failure::Usage(e.to_string())
    }
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Usage(m)) => {
            eprintln!("wip: {m}\n{USAGE}");
            ExitCode::from(2)
        }
        Err(Failure::Run(m)) => {
            eprintln!("wip: error: {m}");
            ExitCode::from(1)
        }
    }
}

fn run() -> Result<(), Failure> {
    let mut parser = lexopt::Parser::from_env();
    let sub = match parser.next()? {
        Some(Value(v)) => v.string()?,
        Some(Long("help")) | Some(Short('h')) => {
            println!("{USAGE}");
            return Ok(());
        }
        Some(a) => return Err(Failure::Usage(a.unexpected().to_string())),
        None => return Err(Failure::Usage("missing subcommand".into())),
    };
    match sub.as_str() {
        "simulate" => cmd_simulate(parser),
        other => Err(Failure::Usage(format!("unknown subcommand '{other}'"))),
    }
}

fn parse_f64(s: &str, what: &str) -> Result<f64, Failure> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| Failure::Run(format!("{what}: '{s}' is not a finite number")))
}

fn load_params(path: Option<PathBuf>) -> Result<WipParams, Failure> {
    match path {
        None => Ok(WipParams::default()),
        Some(p) => WipParams::from_file(&p).map_err(Failure::Run),
    }
}

fn cmd_simulate(mut parser: lexopt::Parser) -> Result<(), Failure> {
    let (mut x0, mut inputs, mut params, mut out) = (None, None, None, PathBuf::from("out"));
    let mut integrator = "varint".to_string();
    let mut h = 0.005;
    while let Some(arg) = parser.next()? {
        match arg {
            Long("x0") => x0 = Some(parser.value()?.string()?),
            Long("inputs") => inputs = Some(PathBuf::from(parser.value()?)),
            Long("integrator") => integrator = parser.value()?.string()?,
            Long("h") => h = parse_f64(&parser.value()?.string()?, "--h")?,
            Long("params") => params = Some(PathBuf::from(parser.value()?)),
            Long("out") => out = PathBuf::from(parser.value()?),
            Long("help") | Short('h') => {
                println!("{SIMULATE_HELP}");
                return Ok(());
            }
            other => return Err(Failure::Usage(other.unexpected().to_string())),
        }
    }
    let x0 = x0.ok_or_else(|| Failure::Usage("simulate: --x0 is required".into()))?;
    let inputs = inputs.ok_or_else(|| Failure::Usage("simulate: --inputs is required".into()))?;
    let integrator: Integrator = integrator.parse().map_err(Failure::Usage)?;
    if !(h > 0.0 && h <= 1.0) {
        return Err(Failure::Run(format!("--h must be in (0, 1] s, got {h}")));
    }

    let fields: Vec<&str> = x0.split(',').collect();
    if fields.len() != 9 {
        return Err(Failure::Run(format!(
            "--x0 needs 9 comma-separated numbers (x,y,theta,alpha,v_alpha,v_d,v_theta,iR,iL), got {}",
            fields.len()
        )));
    }
    let mut x = ReducedState::zeros();
    for (i, f) in fields.iter().enumerate() {
        x[i] = parse_f64(f, &format!("--x0 component {}", i + 1))?;
    }
    let params = load_params(params)?;
    let sched = read_inputs(&inputs).map_err(Failure::Run)?;
    let n = (sched.end() / h).round() as usize;
    if n == 0 {
        return Err(Failure::Run(format!(
            "the inputs file ends at t = {}: the horizon must be at least one step (h = {h})",
            sched.end()
        )));
    }

    let wip = Wip::new(params);
    let t0 = std::time::Instant::now();
    let traj = simulate(&wip, integrator, h, &x, &sched, n).map_err(Failure::Run)?;
    let elapsed = t0.elapsed().as_secs_f64();
    write_atomic(&out, "trajectory.csv", trajectory_csv(&traj).as_bytes()).map_err(Failure::Run)?;
    let xf = traj.x.last().expect("at least one state");
    println!(
        "simulated {n} steps of {h} s with {} in {elapsed:.3} s; final state x={:.6} y={:.6} theta={:.6} alpha={:.6} v_d={:.6} v_theta={:.6} iR={:.6} iL={:.6}",
        integrator.name(),
        xf[0], xf[1], xf[2], xf[3], xf[5], xf[6], xf[7], xf[8]
    );
    println!("wrote {}", out.join("trajectory.csv").display());
    Ok(())
}
