//! `eitskin serve FLEET.toml`: many sensors in one process, each an `eitskin run` of its own
//! (spec, source, calibration or learned model, what it publishes), on one Zenoh session and
//! one pool of threads.
//!
//! Each sensor's source is read as `run` reads it (a thread of its own; a Zenoh source hands its
//! frames over on Zenoh's thread); a sensor with items
//! waiting is put on a queue, and the pool's threads take sensors from it, each taking every
//! item its sensor has (in order: a sensor is on one thread at a time) through its pipeline to
//! its sinks. A sensor that fails (an error of its sinks, a panic) is reported and dropped;
//! the others go on. A source's own troubles are its events, as in `run` (a serial port
//! unplugged, reconnected; a gap in a bridge's frames). `serve` ends when every source has, and
//! fails if any sensor did.
//!
//! What a sensor derives from its noise (its λ and noise tests, when its reference is taken and
//! as its noise model grows: 10–20 ms each on the paper's sheet) is done off the frame path, by half as
//! many derivation threads as the pool has (at least one), at the lowest priority the system
//! gives (nice 19 on Linux; a loaded machine delays them, never a frame, and never stops them),
//! each stepping aside between its pieces of about a millisecond ([`STEP_ASIDE`]): a hundred
//! sensors taking their references at once hold none of the frames up. Frames go on with what
//! was derived before; a live sensor's frames until its reference's derivation is in are
//! answered at once, as referencing. A source read as fast as it goes (`--fast`, a replay) is
//! not live: its new reference's derivation is done on its last frame, as `run` does, so that
//! every frame after it is imaged.
//!
//! Scaling past one machine: run more `serve`s, each with its share of the sensors; Zenoh routes.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Condvar, Mutex};

use anyhow::{anyhow, bail, Context, Result};
use clap::FromArgMatches;
use eitskin::pipeline::{Deferred, Derivation, Derived, PipelineParams};
use eitskin_io::replay::Speed;
use eitskin_io::source::{Acquired, SourceError};
use eitskin_io::stream::{Event, Start};

use crate::ranges;
use crate::run::acquire::{self, Acquisition};
use crate::run::publish::SessionArgs;
use crate::run::sink::{to_all, Flow, Processed, Sink};
use crate::run::{self, Drained, Processing, Sensor};

/// Flags of `eitskin serve`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The fleet (TOML): `[[sensor]]` tables, each a `name` and `run`, the arguments of an
    /// `eitskin run` of it (paths relative to the fleet file's folder).
    fleet: PathBuf,
    /// Threads of the pool every sensor's frames are processed on, 1 to 256 (default: the cores).
    #[arg(long, value_parser = ranges::whole("a number of threads", 1, 256))]
    threads: Option<usize>,
    #[command(flatten)]
    session: SessionArgs,
}

/// A sensor being served: what `run` drives, stepped by the pool.
struct Running {
    args: run::Args,
    processing: Processing,
    sinks: Vec<Box<dyn Sink>>,
    items: mpsc::Receiver<Result<Acquired, SourceError>>,
    acquisition: Option<Acquisition>,
    params: PipelineParams,
}

/// One sensor's place in the pool.
struct Slot {
    name: String,
    /// Items came since its last step began (set by its source).
    pending: AtomicBool,
    /// On the queue or being stepped: a sensor is on one thread at a time, and on the queue once.
    queued: AtomicBool,
    /// `None` once it ended.
    running: Mutex<Option<Running>>,
    /// Derivations done for it, to give its pipeline at its next step (which drops any made
    /// stale since it asked; they may finish out of order).
    derived: Mutex<Vec<Derived>>,
    /// A derivation of it panicked: its next step ends it, as a panic of its own step would.
    derivation_panicked: AtomicBool,
}

/// The fleet's sensors, the queue of those with items waiting, and how many still run.
struct Pool {
    slots: Vec<Slot>,
    queue: Mutex<VecDeque<usize>>,
    wake: Condvar,
    left: AtomicUsize,
    failed: Mutex<Vec<String>>,
    /// Derivations the sensors asked for, with whose they are, for the derivation threads.
    derivations: Mutex<VecDeque<(usize, Derivation)>>,
    derivation_wake: Condvar,
}

/// Items a sensor takes in one step before the others' turn.
const STEP_ITEMS: usize = 16;

impl Pool {
    /// Sensor `k`'s source handed items over: on the queue with it, unless it is there or being
    /// stepped (whoever steps it sees `pending` after its step).
    fn schedule(&self, k: usize) {
        let slot = &self.slots[k];
        slot.pending.store(true, Ordering::SeqCst);
        if !slot.queued.swap(true, Ordering::SeqCst) {
            self.enqueue(k);
        }
    }

    fn enqueue(&self, k: usize) {
        lock(&self.queue).push_back(k);
        self.wake.notify_one();
    }

    /// The next sensor with items waiting; `None` once every sensor ended.
    fn next(&self) -> Option<usize> {
        let mut queue = lock(&self.queue);
        loop {
            if let Some(k) = queue.pop_front() {
                return Some(k);
            }
            if self.left.load(Ordering::SeqCst) == 0 {
                return None;
            }
            queue = self.wake.wait(queue).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// A pool thread: takes sensors off the queue and up to [`STEP_ITEMS`] of their items
    /// through them, until all ended.
    fn work(&self) {
        while let Some(k) = self.next() {
            let slot = &self.slots[k];
            slot.pending.store(false, Ordering::SeqCst);
            let mut running = lock(&slot.running);
            let mut more = false;
            // Everything of the step, the sensor's end included, under one catch: a panic drops
            // the sensor, never the thread.
            let step = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| -> Option<Result<&'static str>> {
                let sensor = running.as_mut()?;
                if slot.derivation_panicked.load(Ordering::SeqCst) {
                    *running = None;
                    return Some(Err(anyhow!("a derivation of its noise tests panicked")));
                }
                let derived = std::mem::take(&mut *lock(&slot.derived));
                derived.into_iter().for_each(|d| sensor.processing.pipeline.deliver(d));
                let drained = sensor.processing.drain(&sensor.items, &mut sensor.sinks, STEP_ITEMS);
                if let Some(job) = sensor.processing.pipeline.take_derivation() {
                    // A new reference's first: its sensor images nothing until it is in.
                    let mut queue = lock(&self.derivations);
                    match job.is_reference() {
                        true => queue.push_front((k, job)),
                        false => queue.push_back((k, job)),
                    }
                    self.derivation_wake.notify_one();
                }
                let outcome = match drained {
                    Ok(Drained::Waiting) => return None,
                    Ok(Drained::More) => {
                        more = true;
                        return None;
                    }
                    Ok(Drained::Ended(tally)) if tally.stopped => Ok("a sink stopped it"),
                    Ok(Drained::Ended(tally)) => sensor
                        .acquisition
                        .take()
                        .map_or(Ok(()), Acquisition::finish)
                        .and_then(|()| run::ended(&sensor.args, tally, &sensor.processing, &sensor.params))
                        .map(|()| "its source ended"),
                    Err(e) => Err(e),
                };
                *running = None;
                Some(outcome)
            }));
            let outcome = match step {
                Ok(None) => None,
                Ok(Some(outcome)) => Some(outcome),
                Err(_) => Some(Err(anyhow!("its processing panicked"))),
            };
            let Some(outcome) = outcome else {
                drop(running);
                // Its turn is over: back on the queue if items came meanwhile (or are left).
                slot.queued.store(false, Ordering::SeqCst);
                if more || slot.pending.load(Ordering::SeqCst) {
                    self.schedule(k);
                }
                continue;
            };
            // A panic while dropping it leaves it dropped or poisoned: either way, it is over.
            *running = None;
            drop(running);
            match outcome {
                Ok(why) => eprintln!("eitskin serve: {}: ended, {why}", slot.name),
                Err(e) => {
                    eprintln!("eitskin serve: {}: failed, the others go on: {e:#}", slot.name);
                    lock(&self.failed).push(slot.name.clone());
                }
            }
            if self.left.fetch_sub(1, Ordering::SeqCst) == 1 {
                // The last one: every thread waiting on a queue goes home.
                let _queue = lock(&self.queue);
                self.wake.notify_all();
                let _derivations = lock(&self.derivations);
                self.derivation_wake.notify_all();
            }
        }
    }

    /// A derivation thread: runs the sensors' derivations as they are asked for, each result
    /// left for its sensor's next step, until all sensors ended.
    fn derive(&self) {
        lowest_priority();
        eitskin::parallel::set_step_aside(STEP_ASIDE);
        loop {
            let (k, job) = {
                let mut queue = lock(&self.derivations);
                loop {
                    if self.left.load(Ordering::SeqCst) == 0 {
                        return;
                    }
                    if let Some(next) = queue.pop_front() {
                        break next;
                    }
                    queue = self.derivation_wake.wait(queue).unwrap_or_else(|e| e.into_inner());
                }
            };
            // A panic in it is the sensor's: its next step ends it (its pipeline would wait for
            // the result for ever).
            let slot = &self.slots[k];
            match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job.run())) {
                Ok(derived) => lock(&slot.derived).push(derived),
                Err(_) => slot.derivation_panicked.store(true, Ordering::SeqCst),
            }
            self.schedule(k);
        }
    }
}

/// How long a derivation thread sleeps between the pieces of a derivation: long enough for the
/// core to count as idle, so that a frame's thread waiting on the other core's queue is moved
/// to it at once. In the 100-sensor benchmark, p99 in 2-s windows while the fleet's first 300
/// derivations ran fell from 13–25 ms to 2.5–7 ms; it adds about 1 ms to a derivation of 11.
const STEP_ASIDE: std::time::Duration = std::time::Duration::from_micros(50);

/// Puts the calling thread at the lowest priority of the normal scheduler (nice 19 on Linux):
/// a frame's thread, at nice 0, takes the core from it at once, and when other processes keep
/// every core busy it still gets its small share (about 1.5 %), so a reference is derived late
/// rather than never (`SCHED_IDLE`, used before, gave it nothing for as long as a build ran
/// beside the fleet; in the 100-sensor benchmark its derivations ended 55 s in, at nice 19
/// 22–31 s). Elsewhere, or if refused, it stays as it was.
fn lowest_priority() {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: `gettid` and `setpriority` take plain integers and touch no memory of ours;
        // on Linux a nice value is per thread, and 19 is the lowest priority there is.
        #[allow(unsafe_code, reason = "the one call that sets a thread's priority")]
        let refused = unsafe { libc::setpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t, 19) } != 0;
        if refused {
            eprintln!("eitskin serve: derivations run at the normal priority (nice 19 refused)");
        }
    }
}

/// A lock, taken even from a thread that panicked holding it (a sensor's panic is caught and the
/// sensor dropped; the pool's own state stays whole).
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|e| e.into_inner())
}

/// A sensor's events on stderr, with its name: the fleet's log.
struct Reporting(String);

impl Sink for Reporting {
    fn event(&mut self, event: &Event) -> Result<Flow> {
        if !matches!(event, Event::Start(_)) {
            eprintln!("eitskin serve: {}: {}", self.0, serde_json::to_string(event).unwrap_or_default());
        }
        Ok(Flow::Go)
    }
    fn frame(&mut self, _frame: &Processed<'_>) -> Result<Flow> {
        Ok(Flow::Go)
    }
}

/// The flags `serve` holds for the whole fleet, which a sensor's `run` must not give.
const FLEET_FLAGS: [&str; 6] =
    ["--sensor", "--zenoh-config", "--zenoh-mode", "--connect", "--listen", "--no-multicast-scouting"];

/// A sensor's `run` arguments parsed as `eitskin run` parses its own, with its name as `--sensor`.
fn parse_run(name: &str, run: &[String]) -> Result<run::Args> {
    if let Some(flag) = run.iter().find(|a| FLEET_FLAGS.iter().any(|f| a == f || a.starts_with(&format!("{f}=")))) {
        bail!("{flag} is the fleet's: a sensor's name is its `name`, and the Zenoh session is serve's flags");
    }
    let command = <run::Args as clap::Args>::augment_args(clap::Command::new("run").no_binary_name(true))
        .mut_args(|arg| if arg.get_action().takes_values() { arg.allow_negative_numbers(true) } else { arg });
    let said = |e: clap::Error| anyhow!("{}", e.render().to_string().trim_start_matches("error: ").trim_end());
    let matches = command.try_get_matches_from(run).map_err(said)?;
    let mut args = run::Args::from_arg_matches(&matches).map_err(said)?;
    args.zenoh.sensor = name.to_owned();
    Ok(args)
}

/// A sensor's pipeline, sinks (its start line taken), source and settings.
type Built = (Processing, Vec<Box<dyn Sink>>, eitskin_io::source::Source, PipelineParams, Start);

/// Builds sensor `name` as `run` would, its events reported on stderr.
fn build(args: &run::Args, name: &str, session: Option<&eitskin_io::middleware::Session>) -> Result<Built> {
    let Sensor { spec, mut processing, start, params } = run::prepare(args)?;
    processing.quiet();
    // Frames read as fast as they go (a replay) wait for a new reference's derivation, each
    // imaged as `run` images it; live ones are answered at once, those meanwhile referencing.
    let deferred = match run::speed(args) {
        Speed::AsFastAsPossible => Deferred::Refreshes,
        Speed::Recorded => Deferred::All,
    };
    processing.pipeline.defer_derivations(deferred);
    let source = run::open_source(args, &spec, processing.kind(), session)?;
    let mut sinks = run::sinks(args, &spec, &processing.pipeline, processing.kind(), session)?;
    sinks.push(Box::new(Reporting(name.to_owned())));
    Ok((processing, sinks, source, params, start))
}

/// Runs `eitskin serve`.
pub fn serve(args: Args) -> Result<()> {
    let fleet = eitskin_io::read_fleet(&args.fleet)?;
    let session_flags = args.session.absolute()?;
    if let Some(folder) = args.fleet.parent().filter(|f| !f.as_os_str().is_empty()) {
        std::env::set_current_dir(folder).with_context(|| format!("cannot move into {}", folder.display()))?;
    }
    let file = args.fleet.display();
    // Every sensor's flags checked before any work.
    let mut parsed: Vec<run::Args> = Vec::with_capacity(fleet.sensors.len());
    let mut zenoh = false;
    for sensor in &fleet.sensors {
        let said = |e: anyhow::Error| e.context(format!("{file}: sensor {}", sensor.name));
        let run_args = parse_run(&sensor.name, &sensor.run).map_err(said)?;
        zenoh |= run::check(&run_args).map_err(said)?;
        if !run_args.publishes() {
            return Err(said(anyhow!(
                "it publishes nothing and records nothing: add --publish zenoh or ros2 (or --record FILE) to its run"
            )));
        }
        // Two sensors cannot record into one file, or serve their pages on one address.
        let (record, viewer) = (run_args.record(), run_args.viewer().filter(|a| a.port() != 0));
        for (other, taken) in fleet.sensors.iter().zip(&parsed) {
            if let Some(path) = record.filter(|p| taken.record() == Some(*p)) {
                return Err(said(anyhow!("--record {} is sensor {}'s already", path.display(), other.name)));
            }
            if let Some(addr) = viewer.filter(|a| taken.viewer() == Some(*a)) {
                return Err(said(anyhow!("--viewer {addr} is sensor {}'s already", other.name)));
            }
        }
        parsed.push(run_args);
    }
    if zenoh {
        session_flags.check()?;
    } else if let Some(flag) = session_flags.given().first() {
        bail!("{flag} sets up Zenoh, which no sensor of {file} uses");
    }
    let session = if zenoh { Some(session_flags.open()?) } else { None };
    let slots = fleet
        .sensors
        .iter()
        .map(|s| Slot {
            name: s.name.clone(),
            pending: AtomicBool::new(false),
            queued: AtomicBool::new(false),
            running: Mutex::new(None),
            derived: Mutex::new(Vec::new()),
            derivation_panicked: AtomicBool::new(false),
        })
        .collect();
    let pool = Arc::new(Pool {
        slots,
        queue: Mutex::new(VecDeque::new()),
        wake: Condvar::new(),
        left: AtomicUsize::new(parsed.len()),
        failed: Mutex::new(Vec::new()),
        derivations: Mutex::new(VecDeque::new()),
        derivation_wake: Condvar::new(),
    });
    // Every sensor built (its pipeline, its publishers) before any source is read; one that
    // cannot be (a port missing, a file unreadable) is reported, and the others go on.
    let mut built = Vec::with_capacity(parsed.len());
    for (k, run_args) in parsed.into_iter().enumerate() {
        let name = &fleet.sensors[k].name;
        match build(&run_args, name, session.as_ref()) {
            Ok((processing, sinks, source, params, start)) => {
                built.push((k, run_args, processing, sinks, source, params, start))
            }
            Err(e) => {
                eprintln!("eitskin serve: {name}: failed to start, the others go on: {e:#}");
                lock(&pool.failed).push(name.clone());
                pool.left.fetch_sub(1, Ordering::AcqRel);
            }
        }
    }
    let mut precisions: Vec<_> = built.iter_mut().map(|b| (b.1.precision(), &mut b.2.pipeline)).collect();
    run::choose_precision("serve", &mut precisions);
    let threads = args.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    // The pool spreads the sensors over the cores: each sensor's products stay on its thread.
    eitskin::parallel::set_par(eitskin::parallel::Par::Seq);
    // And the derivations' products stay on their (lowest-priority) threads: a parallel
    // product would wake threads of the normal priority, which wait for each other, spinning.
    eitskin::faer::set_global_parallelism(eitskin::faer::Par::Seq);
    eprintln!("eitskin serve: {} sensors on {threads} threads", built.len());
    for (k, run_args, processing, mut sinks, source, params, start) in built {
        let notify = Arc::clone(&pool);
        let (items, acquisition) = acquire::start_notifying(source, move || notify.schedule(k));
        // The start line (and a publisher's liveliness token) once the source is read: a bridge
        // that starts on seeing them loses no frame.
        if let Err(e) = to_all(&mut sinks, |s| s.start(&start)) {
            let name = &pool.slots[k].name;
            eprintln!("eitskin serve: {name}: failed to start, the others go on: {e:#}");
            lock(&pool.failed).push(name.clone());
            pool.left.fetch_sub(1, Ordering::AcqRel);
            continue;
        }
        *lock(&pool.slots[k].running) =
            Some(Running { args: run_args, processing, sinks, items, acquisition: Some(acquisition), params });
        // Items that came before the sensor was in place are taken now.
        pool.schedule(k);
    }
    // Named, so that a profiler tells the frame path from the derivations.
    let spawn = |name: &str, job: fn(&Pool)| {
        let pool = Arc::clone(&pool);
        std::thread::Builder::new().name(name.to_owned()).spawn(move || job(&pool))
    };
    let workers = (0..threads).map(|_| spawn("eitskin-pool", Pool::work)).collect::<std::io::Result<Vec<_>>>()?;
    let deriving = (0..(threads / 2).max(1))
        .map(|_| spawn("eitskin-derive", Pool::derive))
        .collect::<std::io::Result<Vec<_>>>()?;
    for worker in workers.into_iter().chain(deriving) {
        if worker.join().is_err() {
            bail!("a thread of the pool panicked");
        }
    }
    let failed = lock(&pool.failed);
    if !failed.is_empty() {
        bail!("{} of {} sensors failed: {}", failed.len(), fleet.sensors.len(), failed.join(", "));
    }
    Ok(())
}
