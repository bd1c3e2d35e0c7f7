//! Development driver: `cargo run --release -p robots --example plan_try -- H [varint|rk1]`.
use dmech_ocp::ipm::IpOptions;
use robots::wip::benchmarks;
use robots::wip::plan::{plan, Transcription};
use robots::wip::Wip;
fn main() {
    if std::env::var("DUMP").is_ok() {
        dump();
        return;
    }
    let args: Vec<String> = std::env::args().collect();
    let h: f64 = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(0.02);
    let tr = match args.get(2).map(|s| s.as_str()) {
        Some("rk1") => Transcription::Rk(dmech::RungeKutta::Rk1),
        _ => Transcription::VarInt,
    };
    let wip = Wip::default();
    let p = match std::env::var("PROB") {
        Ok(f) if f == "zigzag" => benchmarks::zigzag(h),
        Ok(f) => benchmarks::from_file(std::path::Path::new(&f), h).unwrap(),
        _ => benchmarks::eight(h),
    };
    let opts = IpOptions {
        verbose: true,
        ..Default::default()
    };
    let o = plan(&wip, &p, tr, opts);
    println!(
        "{:?} iters {} obj {} viol {:.2e} {:?}",
        o.status, o.iterations, o.objective, o.max_violation, o.timings
    );
}
#[allow(dead_code)]
fn dump() {
    let wip = Wip::default();
    let p = benchmarks::zigzag(0.005);
    let (xs, ws) = robots::wip::plan::varint_start(&wip, &p);
    for k in [0, 1, 2, 100] {
        println!("{k}: x {:?}\n w {:?}", xs[k].as_slice(), ws[k].as_slice());
    }
}
