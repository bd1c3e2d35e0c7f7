//! Transparent huge pages for the solver's large per-stage buffers.
//!
//! The per-stage arrays (derivatives, SR1 blocks, condensed stages, the Riccati sweep's
//! cost-to-go: some 90 MB at 4235 stages) are streamed through at every iteration. On
//! 4 kB pages each pass misses the TLB at every page, and the first touch faults once per
//! page. Linux backs a range with 2 MiB pages where it is asked to (`MADV_HUGEPAGE`, the
//! `madvise` setting of `transparent_hugepage`, the common default). A hint: where the
//! kernel declines (THP off, no free huge page, another OS) the memory is what it was.

use std::mem::MaybeUninit;

const HUGE_PAGE: usize = 2 << 20;

/// Ask for huge pages under `buf` (unwritten memory, before its first touch) if it spans
/// at least two of them; only its whole, aligned 2 MiB pages can be backed so.
pub(crate) fn advise<T>(buf: &mut [MaybeUninit<T>]) {
    let bytes = std::mem::size_of_val(buf);
    if bytes < 2 * HUGE_PAGE {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        let first = buf.as_mut_ptr() as usize;
        let start = first.next_multiple_of(HUGE_PAGE);
        let end = (first + bytes) / HUGE_PAGE * HUGE_PAGE;
        if end > start {
            // SAFETY: `start..end` lies inside `buf`; MADV_HUGEPAGE changes how the range
            // is backed, not its contents or its validity. The result is not checked: a
            // refused hint leaves the memory as it was.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
}

/// `v.resize(n, value)`, with the hint on the memory a growth allocates.
pub(crate) fn resize<T: Clone>(v: &mut Vec<T>, n: usize, value: T) {
    if n > v.capacity() {
        v.reserve_exact(n - v.len());
        advise(v.spare_capacity_mut());
    }
    v.resize(n, value);
}

#[cfg(test)]
mod tests {
    /// `resize` is `Vec::resize` (the hint only changes how the memory is backed), also
    /// across a growth large enough to be advised, and the buffers stay writable.
    #[test]
    fn resize_keeps_and_fills_like_vec_resize() {
        let big = 3 * super::HUGE_PAGE / std::mem::size_of::<u64>();
        let mut v: Vec<u64> = (0..10).collect();
        let mut want = v.clone();
        for (n, fill) in [(big, 7), (5, 1), (big + 3, 9), (0, 2), (big, 4)] {
            super::resize(&mut v, n, fill);
            want.resize(n, fill);
            assert_eq!(v, want, "n = {n}");
        }
        v.iter_mut().enumerate().for_each(|(i, x)| *x = i as u64);
        assert_eq!(v[big - 1], big as u64 - 1);
    }
}
