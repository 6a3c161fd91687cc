//! Work split over a few threads for material builds (the paint's layer tables).
//!
//! Plain scoped OS threads joined with `pthread_join`, not the rayon pool the batch calls use:
//! a build is a handful of equal, independent chunks, and race detectors (valgrind's DRD in
//! `c-api/test.sh`, which builds paints on several threads at once) understand thread joins
//! but not a work-stealing pool's atomics.

/// `f(0), f(1), …, f(n − 1)` in order, computed on up to [`crate::batch::thread_count`]
/// threads (contiguous chunks; the calling thread takes the first). Each `f(k)` is computed
/// exactly as on one thread, so the result does not depend on the thread count. A panic in
/// any chunk resumes on the calling thread after every thread has been joined.
pub(crate) fn map_indices<R: Send>(n: usize, f: impl Fn(usize) -> R + Sync) -> Vec<R> {
    map_indices_on(crate::batch::thread_count(), n, f)
}

/// [`map_indices`] on up to `threads` threads.
fn map_indices_on<R: Send>(threads: usize, n: usize, f: impl Fn(usize) -> R + Sync) -> Vec<R> {
    let threads = threads.clamp(1, n.max(1));
    if threads == 1 {
        return (0..n).map(f).collect();
    }
    let chunk = n.div_ceil(threads);
    let f = &f;
    std::thread::scope(|scope| {
        let others: Vec<_> = (1..threads)
            .map(|t| {
                let range = (t * chunk).min(n)..((t + 1) * chunk).min(n);
                scope.spawn(move || range.map(f).collect::<Vec<R>>())
            })
            .collect();
        let mut out: Vec<R> = (0..chunk.min(n)).map(f).collect();
        let mut panic = None;
        // Every handle is joined explicitly (a `pthread_join`), also after a panic.
        for h in others {
            match h.join() {
                Ok(part) => out.extend(part),
                Err(p) => panic = panic.or(Some(p)),
            }
        }
        if let Some(p) = panic {
            std::panic::resume_unwind(p);
        }
        out
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn map_indices_keeps_order_for_every_length_and_thread_count() {
        for threads in [1, 2, 3, 7] {
            for n in [0, 1, 2, 3, 5, 48, 49] {
                let got = map_indices_on(threads, n, |k| k * k + 1);
                let want: Vec<usize> = (0..n).map(|k| k * k + 1).collect();
                assert_eq!(got, want, "{threads} threads, n = {n}");
            }
        }
    }

    #[test]
    fn map_indices_resumes_a_chunk_panic_on_the_caller() {
        let r = std::panic::catch_unwind(|| {
            map_indices_on(3, 8, |k| {
                assert!(k != 6, "chunk panic");
                k
            })
        });
        assert!(r.is_err());
    }
}
