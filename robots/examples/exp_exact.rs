// Temporary experiment (not committed): iteration counts with the exact Hessian.
use dmech::Discretisation;
use dmech_ocp::solver::IpOptions;
use robots::wip::benchmarks::{eight, zigzag};
use robots::wip::plan::{plan, CurrentModel, PlanBounds, Transcription};
use robots::wip::{Wip, WipParams};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let h: f64 = args[1].parse().unwrap();
    let exact = args[2] == "exact";
    let which = &args[3];
    let p = if which == "eight" {
        eight(h)
    } else {
        zigzag(h)
    };
    let wip = Wip::new(WipParams::default());
    let opts = IpOptions {
        exact_hessian: exact,
        quasi_newton: !exact,
        verbose: true,
        ..IpOptions::default()
    };
    let t = std::time::Instant::now();
    let o = plan(
        &wip,
        &p,
        PlanBounds::default(),
        Transcription::VarInt(Discretisation::FirstOrder),
        CurrentModel::Dynamic,
        opts,
    );
    eprintln!(
        "RESULT {:?} its {} J {} t {:.2} {:?}",
        o.status,
        o.iterations,
        o.objective,
        t.elapsed().as_secs_f64(),
        o.timings
    );
}
