//! Command-line arguments shared by the robots' tools.

use dmech_ocp::ipm::IpOptions;

/// `--hessian`: the curvature of the constraints in the solver's Newton systems.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum HessianArg {
    /// A partitioned SR1 approximation per stage, updated from the exact Jacobians
    Sr1,
    /// The exact second derivatives (by blocks for the first-order VI; several times the
    /// cost of an SR1 iteration, docs/ocp.md)
    Exact,
}

impl HessianArg {
    /// `opts` with this curvature.
    pub fn apply(self, opts: IpOptions) -> IpOptions {
        let exact = self == HessianArg::Exact;
        IpOptions {
            exact_hessian: exact,
            quasi_newton: !exact,
            ..opts
        }
    }
}

/// glibc's allocator told to keep freed large blocks in the process's heap.
///
/// Why: the solver allocates and frees arrays of a few MB at every iteration (the step, the
/// trial points, their values). By default glibc maps each such block afresh and unmaps it
/// when it is freed, or trims the heap's top back to the system, and the kernel then
/// zero-fills every page again when it is touched: 16,000 of the 44,000 page faults of
/// `wip plan eight` (docs/ocp.md, "What is left"). With blocks up to 64 MiB served from the
/// heap (32 MiB where glibc refuses more) and the heap trimmed only above 128 MiB free,
/// they are reused instead. The blocks are the same size at every iteration, so the heap
/// does not grow with them (measured: peak memory fell, 120 → 115 MiB on the eight and
/// 127 → 107 MiB on the zigzag). A no-op on other C libraries.
pub fn keep_freed_blocks() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters; it is called before any thread that
    // allocates is started.
    unsafe {
        if libc::mallopt(libc::M_MMAP_THRESHOLD, 64 << 20) == 0 {
            libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        }
        libc::mallopt(libc::M_TRIM_THRESHOLD, 128 << 20);
    }
}

/// `f` run on a thread with the stack of the solver's stage-loop threads
/// ([`dmech_ocp::ipm::STAGE_THREAD_STACK`]): with one thread the stage loops run on the
/// calling thread, and a tool's main thread has only the 8 MiB the system gives it. If no
/// thread can be started, `f` runs here. A panic in `f` carries on here.
pub fn on_solver_stack<R: Send, F: FnOnce() -> R + Send>(f: F) -> R {
    let mut task = Some(f);
    let ran = std::thread::scope(|sc| {
        let spawned = std::thread::Builder::new()
            .stack_size(dmech_ocp::ipm::STAGE_THREAD_STACK)
            .spawn_scoped(sc, || task.take().map(|f| f()));
        match spawned {
            Ok(h) => h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)),
            Err(_) => None,
        }
    });
    ran.unwrap_or_else(|| (task.take().expect("the command runs once"))())
}
