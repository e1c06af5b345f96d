//! A second core for the image product, while it is free: one helper thread takes chunks of
//! pixel blocks from the far end of the image while the caller takes them from the near end.
//!
//! One core reads the 2 MB matrix of the paper's sensor at the rate of the shared cache
//! (about 21 µs a frame here); two cores read it in about half that, and each end tends to
//! stay in its own core's cache from frame to frame. The caller never waits for the helper to
//! start: it claims chunks until none is left and then waits only for the chunks the helper has
//! already claimed. A helper that is busy elsewhere, asleep or never started costs a frame
//! nothing but the claims. The helper spins for [`SPIN`] after its last chunk, then sleeps;
//! a product wakes it only when it follows the last one within [`SPIN`], so at a board's
//! frame rate (below about 5 kHz) the helper sleeps and costs nothing, while images made back
//! to back (a replay, a batch, a benchmark) share the work.
//!
//! rayon's `join` was measured first on the same product: 18 µs at best but 33 µs median from a
//! thread outside its pool, slower than one core; fork–join crates that share work on a
//! heartbeat (chili: 100 µs) never share work as short as this. Hence this small protocol.
//!
//! The state of a product is one atomic word (generation, near end, far end), so a claim is
//! one compare-and-swap that also proves the product is still the one whose buffers it names.
//! The caller publishes a product's kernel and its generation under one lock, and the helper
//! holds that lock while it claims and runs chunks, so the kernel it calls is always the one
//! of the generation its claims succeed on: a generation that wraps (2²⁴ products) can make
//! the helper miss a product, which the caller then does alone, never run a stale kernel. A
//! caller that finds the lock held (the helper leaving the last product) works alone.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock, PoisonError};
use std::thread::Thread;
use std::time::{Duration, Instant};

/// How long the helper spins for the next product after its last chunk before it sleeps.
pub const SPIN: Duration = Duration::from_micros(200);

/// Bits of the near and far ends in the state word; the generation has the rest.
const END_BITS: u32 = 20;
const END_MASK: u64 = (1 << END_BITS) - 1;

/// One chunk of work: `run(chunk)` for chunk in 0..chunks, each chunk writing only its own part
/// of the output.
type Kernel = dyn Fn(usize) + Sync;

/// A product in progress, as the helper sees it: a pointer to the caller's kernel, valid while
/// the generation published with it (under the same lock) still has chunks to claim.
#[derive(Clone, Copy)]
struct Job {
    kernel: *const Kernel,
}

// SAFETY: the kernel is `Sync`; the helper calls it only after a claim that proves the caller
// is still inside `run_split`, which keeps it alive (see `Helper::serve`).
#[allow(unsafe_code, reason = "the job's kernel is shared with the helper only while the caller waits for it")]
unsafe impl Send for Job {}

struct Helper {
    /// Generation (high bits), near end, far end: chunks near..far are unclaimed.
    state: AtomicU64,
    /// Chunks of the current generation finished by the helper.
    done: AtomicUsize,
    job: Mutex<Option<Job>>,
    sleeping: AtomicBool,
    /// When the last product started, in ns since [`start`].
    last: AtomicU64,
    /// Whether a product is in progress (one at a time; a second caller works alone).
    busy: AtomicBool,
    thread: OnceLock<Thread>,
}

fn pack(generation: u64, near: usize, far: usize) -> u64 {
    (generation << (2 * END_BITS)) | ((near as u64) << END_BITS) | far as u64
}

fn unpack(state: u64) -> (u64, usize, usize) {
    (state >> (2 * END_BITS), ((state >> END_BITS) & END_MASK) as usize, (state & END_MASK) as usize)
}

impl Helper {
    /// Claims the next chunk of `generation` from the near end (the caller) or the far end.
    fn claim(&self, generation: u64, far_end: bool) -> Option<usize> {
        let mut state = self.state.load(Ordering::Acquire);
        loop {
            let (g, near, far) = unpack(state);
            if g != generation || near >= far {
                return None;
            }
            let (next, chunk) =
                if far_end { (pack(g, near, far - 1), far - 1) } else { (pack(g, near + 1, far), near) };
            match self.state.compare_exchange_weak(state, next, Ordering::AcqRel, Ordering::Acquire) {
                Ok(_) => return Some(chunk),
                Err(now) => state = now,
            }
        }
    }

    /// The helper's loop: work on each new generation, spin a while, then sleep.
    #[allow(unsafe_code, reason = "calls the kernel of a product whose caller is still waiting for it")]
    fn serve(&self) {
        let mut seen = unpack(self.state.load(Ordering::Acquire)).0;
        let mut idle = Instant::now();
        loop {
            let generation = unpack(self.state.load(Ordering::Acquire)).0;
            if generation != seen {
                seen = generation;
                // Held while chunks are claimed and run: no other product can be published
                // meanwhile, so a claim on `generation` that succeeds is a claim on this job.
                let job = self.job.lock().unwrap_or_else(PoisonError::into_inner);
                if let Some(job) = *job {
                    while let Some(chunk) = self.claim(generation, true) {
                        // SAFETY: the claim succeeded, so this generation, whose kernel `job`
                        // is (both were published under the lock held here), still had chunks
                        // left: its caller is inside `run_split`, which does not return before
                        // every claimed chunk is counted done.
                        call(unsafe { &*job.kernel }, chunk);
                        self.done.fetch_add(1, Ordering::AcqRel);
                    }
                }
                drop(job);
                idle = Instant::now();
            } else if idle.elapsed() < SPIN {
                // Offer the core to any other thread that is ready (a reader decoding the
                // next frames) rather than take it from it; alone, this returns at once.
                std::thread::yield_now();
            } else {
                self.sleeping.store(true, Ordering::SeqCst);
                if unpack(self.state.load(Ordering::SeqCst)).0 == seen {
                    std::thread::park();
                }
                self.sleeping.store(false, Ordering::SeqCst);
                idle = Instant::now();
            }
        }
    }
}

/// `kernel(chunk)`, stopping the process if it panics: the other core may still be writing
/// into the output that an unwinding caller would free (the kernels index within their chunk,
/// so this is a bug, never an input's doing).
fn call(kernel: &(dyn Fn(usize) + Sync + '_), chunk: usize) {
    if std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| kernel(chunk))).is_err() {
        eprintln!(
            "eitskin: the image product panicked on chunk {chunk}; stopping, as another core may be writing its output"
        );
        std::process::abort();
    }
}

/// A fixed instant, for times kept in atomics.
fn start() -> &'static Instant {
    static START: OnceLock<Instant> = OnceLock::new();
    START.get_or_init(Instant::now)
}

/// The helper, started on first use; `None` on a single core or where no thread can start.
fn helper() -> Option<&'static Helper> {
    static HELPER: OnceLock<Option<&'static Helper>> = OnceLock::new();
    *HELPER.get_or_init(|| {
        if std::thread::available_parallelism().map_or(1, |n| n.get()) < 2 {
            return None;
        }
        let helper: &'static Helper = Box::leak(Box::new(Helper {
            state: AtomicU64::new(0),
            done: AtomicUsize::new(0),
            job: Mutex::new(None),
            sleeping: AtomicBool::new(false),
            last: AtomicU64::new(0),
            busy: AtomicBool::new(false),
            thread: OnceLock::new(),
        }));
        let handle = std::thread::Builder::new().name("eitskin-product".into()).spawn(|| helper.serve()).ok()?;
        helper.thread.set(handle.thread().clone()).ok()?;
        Some(helper)
    })
}

/// Runs `kernel(chunk)` for every chunk in 0..`chunks`, the helper taking chunks from the far
/// end while it is free (with [`Par::Two`](super::Par)); each chunk must write only its own
/// part of the output. Allocates nothing after the first call (which starts the helper).
pub fn run_split(chunks: usize, kernel: &(dyn Fn(usize) + Sync)) {
    let alone = || (0..chunks).for_each(kernel);
    if super::par() == super::Par::Seq {
        return alone();
    }
    let Some(helper) = helper().filter(|_| chunks >= 2 && chunks <= END_MASK as usize) else {
        return alone();
    };
    if helper.busy.swap(true, Ordering::Acquire) {
        return alone();
    }
    // The helper still holds the lock after the last product (it is leaving it): work alone.
    let Ok(mut job) = helper.job.try_lock() else {
        helper.busy.store(false, Ordering::Release);
        return alone();
    };
    let generation = (unpack(helper.state.load(Ordering::Acquire)).0 + 1) & (u64::MAX >> (2 * END_BITS));
    helper.done.store(0, Ordering::Release);
    #[allow(unsafe_code, reason = "the kernel outlives every call the helper makes of it; see below")]
    // SAFETY: the pointer's lifetime is erased, but the helper calls it only under a claim of
    // this generation, and this function waits for those calls below before it returns.
    let kernel_ptr: *const Kernel = unsafe { std::mem::transmute::<&(dyn Fn(usize) + Sync), &'static Kernel>(kernel) };
    *job = Some(Job { kernel: kernel_ptr });
    helper.state.store(pack(generation, 0, chunks), Ordering::SeqCst);
    drop(job);
    // A sleeping helper wakes too late for this product (tens of µs): wake it only when
    // products come faster than it spins, for the ones that follow.
    let now = Instant::now();
    let last = helper.last.swap(now.duration_since(*start()).as_nanos() as u64, Ordering::Relaxed);
    let since = now.duration_since(*start()).saturating_sub(Duration::from_nanos(last));
    if since < SPIN && helper.sleeping.load(Ordering::SeqCst) {
        if let Some(thread) = helper.thread.get() {
            thread.unpark();
        }
    }
    let mut mine = 0;
    while let Some(chunk) = helper.claim(generation, false) {
        call(kernel, chunk);
        mine += 1;
    }
    // Every chunk is claimed: wait for the helper's, each already under way.
    // The helper may have lost its core to another thread mid-chunk: spin a little, then
    // offer this core to it.
    let mut spins = 0u32;
    while helper.done.load(Ordering::Acquire) < chunks - mine {
        spins += 1;
        if spins < 4096 {
            std::hint::spin_loop();
        } else {
            std::thread::yield_now();
        }
    }
    helper.busy.store(false, Ordering::Release);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every chunk runs exactly once, from one caller or several at once, many times over.
    #[test]
    fn every_chunk_runs_once() {
        std::thread::scope(|scope| {
            for caller in 0..3 {
                scope.spawn(move || {
                    for round in 0..2000 {
                        let chunks = 1 + (round * 7 + caller) % 40;
                        let counts: Vec<AtomicUsize> = (0..chunks).map(|_| AtomicUsize::new(0)).collect();
                        run_split(chunks, &|c| {
                            counts[c].fetch_add(1, Ordering::Relaxed);
                        });
                        assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 1), "round {round}");
                        if round % 500 == 0 {
                            // Let the helper fall asleep now and then.
                            std::thread::sleep(SPIN * 2);
                        }
                    }
                });
            }
        });
    }

    /// With [`Par::Seq`](super::super::Par) every chunk runs once, on the calling thread.
    #[test]
    fn sequential_work_stays_on_the_calling_thread() {
        use super::super::{set_par, Par};
        set_par(Par::Seq);
        let caller = std::thread::current().id();
        let runs = Mutex::new(Vec::new());
        run_split(40, &|c| runs.lock().unwrap_or_else(PoisonError::into_inner).push((c, std::thread::current().id())));
        set_par(Par::Two);
        let mut runs = runs.into_inner().unwrap_or_else(PoisonError::into_inner);
        runs.sort_by_key(|r| r.0);
        assert_eq!(runs.iter().map(|r| r.0).collect::<Vec<_>>(), (0..40).collect::<Vec<_>>());
        assert!(runs.iter().all(|r| r.1 == caller));
    }
}
