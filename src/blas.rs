//! The system BLAS that OpenCV's calibration and pose solvers call, set up for a program that
//! calls OpenCV from several threads at once (arena tracking runs one camera per thread).
//! `make deps` installs Debian's reference BLAS and LAPACK: thread-safe, without threads of
//! its own, and the same bits on every x86-64 processor. A machine may have OpenBLAS
//! selected instead; this makes the best of it.

use std::ffi::{c_int, CStr};

/// If the BLAS is OpenBLAS: one thread per call, since the pthread build's workers, called
/// from several threads at once, contend for the cores (a calibration 30 times slower on 2
/// cores). Returns a warning when it is OpenBLAS's serial build: Debian builds it without
/// locking, and calls from two threads at once corrupt each other's results.
pub fn one_thread_per_call() -> Option<String> {
    // SAFETY: dlsym with RTLD_DEFAULT only looks a name up among the loaded libraries; the
    // two functions, when present, are OpenBLAS's, with these C signatures.
    unsafe {
        let set = symbol(c"openblas_set_num_threads")?;
        let set: extern "C" fn(c_int) = std::mem::transmute(set);
        set(1);
        let parallel = symbol(c"openblas_get_parallel")?;
        let parallel: extern "C" fn() -> c_int = std::mem::transmute(parallel);
        (parallel() == 0).then(|| {
            let arch = std::env::consts::ARCH;
            format!(
                "warning: the system's BLAS is OpenBLAS's serial build, which gives wrong results \
                 when called from several threads at once (as tracking several cameras does); \
                 run `make deps` in odocal's source, or select Debian's reference BLAS and LAPACK \
                 (packages libblas3, liblapack3) with `update-alternatives --config \
                 libblas.so.3-{arch}-linux-gnu` and the same for liblapack.so.3-{arch}-linux-gnu"
            )
        })
    }
}

unsafe fn symbol(name: &CStr) -> Option<*mut libc::c_void> {
    let p = unsafe { libc::dlsym(libc::RTLD_DEFAULT, name.as_ptr()) };
    (!p.is_null()).then_some(p)
}
