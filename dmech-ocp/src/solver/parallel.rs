//! Stage loops on several threads: work handed out in chunks from a shared counter.

use super::worker_pool;

/// Split `0..n` over `threads` workers and fill `out[k] = f(k)`.
pub(super) fn par_fill<R: Send, F: Fn(usize) -> R + Sync>(out: &mut [R], threads: usize, f: F) {
    par_update(out, threads, |k, slot| *slot = f(k));
}

/// An empty vector with room for `capacity` items, advised to huge pages before anything
/// touches it (untouched room costs no memory). Fill it with [`par_resize`].
pub(super) fn with_room<R>(capacity: usize) -> Vec<R> {
    let mut v = Vec::with_capacity(capacity);
    crate::solver::huge_pages::advise(v.spare_capacity_mut());
    v
}

/// `v` cut or grown to `n` items: the items it keeps are left as they are, new item `k` is
/// `f(k)`, written on `threads` threads into its spare room (grown, with the huge-page
/// hint, if it is short). Why threads: the first touch of each page of the solver's
/// per-stage arrays (some 70 MB at 4235 stages) is a page fault; on one thread the other
/// one would wait through all of them.
pub(super) fn par_resize<R: Send, F: Fn(usize) -> R + Sync>(
    v: &mut Vec<R>,
    n: usize,
    threads: usize,
    f: F,
) {
    if n <= v.len() {
        v.truncate(n);
        return;
    }
    let have = v.len();
    if n > v.capacity() {
        v.reserve_exact(n - have);
        crate::solver::huge_pages::advise(v.spare_capacity_mut());
    }
    let written = std::sync::atomic::AtomicUsize::new(0);
    par_update(
        &mut v.spare_capacity_mut()[..n - have],
        threads,
        |k, slot| {
            slot.write(f(have + k));
            written.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        },
    );
    // `par_update` visits every index once (a worker's panic is resumed here), so all new
    // slots are initialised; the count makes that a checked fact, not an assumption.
    assert_eq!(
        written.into_inner(),
        n - have,
        "par_resize: a slot was not written"
    );
    // SAFETY: slots 0..n are initialised (the kept ones and the ones counted above) and
    // `n` ≤ the capacity.
    unsafe { v.set_len(n) };
}

/// `(0..len).map(f).collect()` built on `threads` threads ([`par_resize`]).
pub(super) fn par_collect<R: Send, F: Fn(usize) -> R + Sync>(
    len: usize,
    threads: usize,
    f: F,
) -> Vec<R> {
    let mut v = Vec::with_capacity(len);
    par_resize(&mut v, len, threads, f);
    v
}

/// Stages per work item of the parallel loops: small enough that two threads finish
/// together (stage costs differ, e.g. where the friction saturates), large enough that
/// taking an item costs nothing against its work.
pub(super) const PAR_CHUNK: usize = 32;

/// `f(k, &mut items[k])` for every `k`, on `threads` scoped threads.
pub(super) fn par_update<R: Send, F: Fn(usize, &mut R) + Sync>(
    items: &mut [R],
    threads: usize,
    f: F,
) {
    let mut none: Vec<()> = vec![(); items.len()];
    par_zip(items, &mut none, threads, |k, a, _| f(k, a));
}

/// `f(k, &mut a[k], &mut b[k])` for every `k`, on `threads` scoped threads (see
/// [`par_zip3`]).
pub(super) fn par_zip<A: Send, B: Send, F: Fn(usize, &mut A, &mut B) + Sync>(
    a: &mut [A],
    b: &mut [B],
    threads: usize,
    f: F,
) {
    let mut none: Vec<()> = vec![(); a.len()];
    par_zip3(a, b, &mut none, threads, |k, x, y, _| f(k, x, y));
}

/// `f(k, &mut a[k], &mut b[k], &mut c[k])` for every `k`, on `threads` scoped threads:
/// per-stage arrays filled in one pass, so that a stage's data is still in cache for the
/// later ones. Threads take chunks of [`PAR_CHUNK`] stages from a shared queue.
pub(super) fn par_zip3<A: Send, B: Send, C: Send, F: Fn(usize, &mut A, &mut B, &mut C) + Sync>(
    a: &mut [A],
    b: &mut [B],
    c: &mut [C],
    threads: usize,
    f: F,
) {
    assert_eq!(a.len(), b.len());
    assert_eq!(a.len(), c.len());
    let chunks = a
        .chunks_mut(PAR_CHUNK)
        .zip(b.chunks_mut(PAR_CHUNK))
        .zip(c.chunks_mut(PAR_CHUNK))
        .enumerate();
    let queue = std::sync::Mutex::new(chunks);
    let work = || loop {
        let next = queue.lock().unwrap_or_else(|p| p.into_inner()).next();
        let Some((ci, ((pa, pb), pc))) = next else {
            break;
        };
        for (j, ((sa, sb), sc)) in pa
            .iter_mut()
            .zip(pb.iter_mut())
            .zip(pc.iter_mut())
            .enumerate()
        {
            f(ci * PAR_CHUNK + j, sa, sb, sc);
        }
    };
    run_on_threads(threads, &work);
}

/// `work()` on `threads` threads at once (inline for one): this one and the kept workers
/// of [`worker_pool`], or scoped threads while the pool is busy. Not generic: the stage
/// loops hand their work in as a trait object, so the thread machinery is compiled once
/// rather than once per loop and problem type (it was a tenth of the code generated for
/// the robots' crate).
fn run_on_threads(threads: usize, work: &(dyn Fn() + Sync)) {
    if threads <= 1 {
        work();
        return;
    }
    if worker_pool::run(threads - 1, work) {
        return;
    }
    std::thread::scope(|sc| {
        for _ in 0..threads {
            let spawned = std::thread::Builder::new()
                .stack_size(STAGE_THREAD_STACK)
                .spawn_scoped(sc, work);
            if spawned.is_err() {
                // The work is handed out from a shared counter: the threads that did
                // start, and this one, finish it.
                work();
            }
        }
    });
}

/// Stack of a stage-loop thread. The generic second derivatives evaluate a stage in
/// nested duals whose numbers are kilobytes each (an RK stage's exact curvature: a
/// vector dual of a dual of a hyper-dual, 576 lanes); the default 2 MiB of a spawned
/// thread overflowed on an RK1 plan with the exact Hessian of a five-dimensional shape. The size is
/// reserved address space, not memory: only the pages touched are committed.
pub const STAGE_THREAD_STACK: usize = 64 << 20;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn par_vec_builds_every_element_in_place() {
        for n in [0, 1, PAR_CHUNK - 1, PAR_CHUNK, 5 * PAR_CHUNK + 7] {
            for threads in [1, 2, 3] {
                let mut v = with_room(n);
                par_resize(&mut v, n, threads, |k| (k, vec![k; k % 3]));
                let want: Vec<_> = (0..n).map(|k| (k, vec![k; k % 3])).collect();
                assert_eq!(v, want, "n = {n}, threads = {threads}");
            }
        }
    }

    /// `par_resize` keeps the items it has and builds the new ones, within its room or
    /// beyond it.
    #[test]
    fn par_resize_keeps_and_builds_like_a_resize() {
        let mut v = with_room(200);
        par_resize(&mut v, 3, 2, |k| k as i64);
        let mut want: Vec<i64> = (0..3).collect();
        for (n, tag) in [(150, 1000), (40, 0), (300, 2000), (0, 0), (70, 3000)] {
            v.iter_mut().for_each(|x| *x = -*x);
            want.iter_mut().for_each(|x| *x = -*x);
            par_resize(&mut v, n, 2, |k| tag + k as i64);
            let have = want.len().min(n);
            want.truncate(have);
            want.extend((have..n).map(|k| tag + k as i64));
            assert_eq!(v, want, "n = {n}");
        }
    }
}
