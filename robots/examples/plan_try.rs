use dmech_ocp::ipm::IpOptions;
use robots::wip::benchmarks;
use robots::wip::plan::{plan, Transcription};
use robots::wip::Wip;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let h: f64 = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(0.02);
    let tr = match args.get(2).map(|s| s.as_str()) { Some("rk1") => Transcription::Rk(dmech::RungeKutta::Rk1), _ => Transcription::VarInt };
    let mut wip = Wip::default(); if std::env::var("NO_COULOMB").is_ok() { wip.params.d_c = 0.0; }
    let p = match std::env::var("PROB") { Ok(f) if f == "zigzag" => benchmarks::zigzag(h), Ok(f) => benchmarks::from_file(std::path::Path::new(&f), h).unwrap(), _ => benchmarks::eight(h) };
    let dc: f64 = std::env::var("DC").map(|s| s.parse().unwrap()).unwrap_or(1e-9); let mu: f64 = std::env::var("MU").map(|s| s.parse().unwrap()).unwrap_or(0.1);
    let dcm: f64 = std::env::var("DCM").map(|s| s.parse().unwrap()).unwrap_or(1e-10);
    let opts = IpOptions { delta_c_min: dcm, quasi_newton: std::env::var("NO_QN").is_err(), convexify: std::env::var("CONVEX").is_ok(), exact_hessian: std::env::var("EXACT").is_ok(), verbose: true, max_iter: 200, mu_init: mu, ..Default::default() };
    let o = plan(&wip, &p, tr, opts);
    println!("{:?} iters {} obj {} viol {:.2e} {:?}", o.status, o.iterations, o.objective, o.max_violation, o.timings);
}
