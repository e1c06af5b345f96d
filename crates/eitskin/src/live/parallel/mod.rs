//! Parallel work on the frame path, in one place: how many cores it uses ([`Par`], set with
//! [`set_par`]), the split of a product between the calling thread and one helper thread
//! ([`run_split`]), the choice of vector instructions for a kernel (`widest!`, crate-private),
//! and how a thread deriving in the background makes way for frames ([`set_step_aside`]).
//!
//! A frame's image is one product of a matrix (2 MB for the paper's sensor) with Δv; it runs
//! at the rate the shared cache reads the matrix. With [`Par::Two`], the default on two or more
//! cores, a helper thread takes part of each large product while it is free, and a product
//! takes about half the time; with [`Par::Seq`] every product runs on the calling thread
//! alone and the helper never starts (or, started before, sleeps). A learned model's variance
//! uses the same split.
//!
//! ```
//! use eitskin::parallel::{par, set_par, Par};
//! set_par(Par::Seq); // the frame path on the calling thread alone
//! assert_eq!(par(), Par::Seq);
//! set_par(Par::Two);
//! ```

mod helper;

use std::sync::atomic::{AtomicU8, Ordering};
use std::time::Duration;

pub use helper::{run_split, SPIN};

/// How many cores the frame path's products use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Par {
    /// The calling thread alone.
    Seq,
    /// The calling thread, and a helper thread that takes part of each large product while it
    /// is free (the default where the machine has two or more cores; one core works alone).
    Two,
}

/// The setting, as [`Par`] numbered: 0 sequential, 1 two cores.
static PAR: AtomicU8 = AtomicU8::new(1);

/// Sets how many cores the frame path's products use, for the whole process, from the next
/// product on.
pub fn set_par(par: Par) {
    PAR.store(if par == Par::Seq { 0 } else { 1 }, Ordering::Relaxed);
}

/// How many cores the frame path's products use (see [`set_par`]).
pub fn par() -> Par {
    if PAR.load(Ordering::Relaxed) == 0 {
        Par::Seq
    } else {
        Par::Two
    }
}

thread_local! {
    /// How long the calling thread sleeps at each [`step_aside`] (zero: it does not).
    static STEP_ASIDE: std::cell::Cell<Duration> = const { std::cell::Cell::new(Duration::ZERO) };
}

/// Makes the calling thread sleep `pause` between the pieces of a long derivation (a λ chosen, a
/// reconstructor derived, a noise test made: pieces of under a millisecond on the paper's
/// sheet, but for the channels' products of a linearisation's first derivation and a
/// reconstructor that estimates a background change, each one piece); `Duration::ZERO`, the
/// default, goes straight on and does each product whole. For a thread that derives
/// beside threads that image frames: a core it holds for tens of milliseconds, even at the
/// lowest priority, is one the scheduler does not hand a waiting frame's thread at once (it
/// balances the two cores' queues every few milliseconds); a core left idle for a moment is
/// handed over at once. The results are the same either way.
pub fn set_step_aside(pause: Duration) {
    STEP_ASIDE.with(|s| s.set(pause));
}

/// Whether the calling thread steps aside between pieces ([`set_step_aside`]): work split
/// into pieces only for that is done whole otherwise.
pub(crate) fn stepping_aside() -> bool {
    !STEP_ASIDE.with(std::cell::Cell::get).is_zero()
}

/// A point between two pieces of a derivation: sleeps as [`set_step_aside`] set for this thread.
pub(crate) fn step_aside() {
    let pause = STEP_ASIDE.with(std::cell::Cell::get);
    if !pause.is_zero() {
        std::thread::sleep(pause);
    }
}

/// Defines `$name`, which runs the `#[inline(always)]` function `$portable` compiled for the
/// widest vectors the processor has (AVX-512, AVX2 with FMA, chosen at run time) or portably:
/// the one dispatch of the crate's vector kernels. The results are the same either way (no
/// operation is fused or reordered that the portable code does not write).
macro_rules! widest {
    ($(#[$doc:meta])* fn $name:ident = $portable:ident($($arg:ident: $ty:ty),*) -> $ret:ty) => {
        $(#[$doc])*
        #[allow(unsafe_code, reason = "calls a kernel compiled for vector extensions only once the processor is known to have them")]
        fn $name($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f")]
                fn avx512($($arg: $ty),*) -> $ret {
                    $portable($($arg),*)
                }
                #[target_feature(enable = "avx2,fma")]
                fn avx2($($arg: $ty),*) -> $ret {
                    $portable($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the features the function is compiled for were just detected.
                    return unsafe { avx512($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
                    // SAFETY: as above.
                    return unsafe { avx2($($arg),*) };
                }
            }
            $portable($($arg),*)
        }
    };
}
pub(crate) use widest;
