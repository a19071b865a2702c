//! The threads that decode frames, shared by every frame source.

/// The threads that decode frames in parallel.
///
/// They are not rayon's global pool: a tracker called from inside a parallel loop blocks its
/// worker while it waits for frames, and decoding queued behind it on the same pool would wait
/// for that worker for ever. With a pool of their own, frame sources work from any thread.
pub(super) fn decode_pool() -> &'static rayon::ThreadPool {
    static POOL: std::sync::OnceLock<rayon::ThreadPool> = std::sync::OnceLock::new();
    POOL.get_or_init(|| {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("odocal-decode-{i}"))
            .build()
            .or_else(|_| rayon::ThreadPoolBuilder::new().num_threads(1).build())
            .unwrap_or_else(|e| panic!("cannot start a frame-decoding thread: {e}"))
    })
}
