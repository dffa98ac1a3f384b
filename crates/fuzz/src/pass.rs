//! The deterministic mutation pass of one reader: the corpus itself, which must be accepted, then
//! `inputs` mutated inputs (cases `first_case..`), each checked for
//!
//! * no panic (caught with `catch_unwind`, reported with its message);
//! * no hang: each input finishes within [`Settings::time_limit`]; a watchdog aborts the
//!   process, naming the input, if one runs past [`Settings::hang_limit`];
//! * an error that names the file ([`Target::names_input`]);
//! * no oversized allocation: that check belongs to the binary's global allocator
//!   ([`crate::alloc::LimitAlloc`]); [`run`] keeps its context current.
//!
//! Every failing input is saved under `target/fuzz-failures/` as `<reader>-<case>.<ext>` and can
//! be replayed by its case number (`FUZZ_CASE`, see `tests/mutations.rs`).

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, Once};
use std::time::{Duration, Instant};

use crate::mutate::Mutator;
use crate::readers::{Reader, Target};
use crate::rng::{hash_name, mix};

/// Settings of a pass.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Mutated inputs.
    pub inputs: u64,
    /// Case number of the first input.
    pub first_case: u64,
    /// Longest an input may take.
    pub time_limit: Duration,
    /// Past this the process is aborted (a hang that would never return).
    pub hang_limit: Duration,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            inputs: 10_000,
            first_case: 0,
            time_limit: Duration::from_secs(2),
            hang_limit: Duration::from_secs(30),
        }
    }
}

/// The seed of case `case` of `reader`.
pub fn case_seed(reader: Reader, case: u64) -> u64 {
    mix(hash_name(reader.name()) ^ mix(case))
}

/// What went wrong with one input.
#[derive(Debug)]
pub enum Problem {
    /// A corpus file was rejected.
    CorpusRejected(String),
    /// The reader panicked.
    Panic(String),
    /// The input took too long.
    Slow(Duration),
    /// The error does not name the file.
    Unnamed(String),
}

/// A failing input.
#[derive(Debug)]
pub struct Failure {
    /// The case number, or the corpus file.
    pub case: String,
    /// What went wrong.
    pub problem: Problem,
    /// Where the input was saved.
    pub saved: PathBuf,
    /// A dump of the input (text, or hex of its start).
    pub dump: String,
}

/// The outcome of a pass.
#[derive(Debug)]
pub struct Report {
    /// The reader.
    pub reader: Reader,
    /// Inputs read (corpus and mutated).
    pub inputs: u64,
    /// Inputs the reader accepted.
    pub accepted: u64,
    /// Inputs it rejected with an error.
    pub rejected: u64,
    /// Panics inside third-party parsers that the reader itself caught and turned into errors.
    pub caught_inside: u64,
    /// The first few of those: case and panic message.
    pub caught_examples: Vec<(String, String)>,
    /// The slowest input: its time and case.
    pub slowest: (Duration, String),
    /// Wall time of the pass.
    pub seconds: f64,
    /// The failing inputs.
    pub failures: Vec<Failure>,
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {} inputs in {:.1} s ({} accepted, {} rejected, {} third-party panics caught by \
             the reader), slowest {:.1} ms (case {}), {} failures",
            self.reader.name(),
            self.inputs,
            self.seconds,
            self.accepted,
            self.rejected,
            self.caught_inside,
            self.slowest.0.as_secs_f64() * 1e3,
            self.slowest.1,
            self.failures.len()
        )?;
        for (case, msg) in &self.caught_examples {
            write!(f, "\n  caught inside the reader, case {case}: {msg}")?;
        }
        for fail in &self.failures {
            write!(
                f,
                "\n\n--- {} case {}: {:?}\n    saved as {}\n{}",
                self.reader.name(),
                fail.case,
                fail.problem,
                fail.saved.display(),
                fail.dump
            )?;
        }
        Ok(())
    }
}

thread_local! {
    static IN_READ: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    static PANICS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    static LAST_PANIC: std::cell::RefCell<String> = const { std::cell::RefCell::new(String::new()) };
}

/// Installs (once) a panic hook that records panics during reads instead of printing them (the
/// pass reports them) and leaves every other panic to the default hook.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if IN_READ.with(|r| r.get()) {
                PANICS.with(|p| p.set(p.get() + 1));
                let msg = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "(no message)".into());
                let at = info
                    .location()
                    .map(|l| format!(" at {}:{}", l.file(), l.line()))
                    .unwrap_or_default();
                LAST_PANIC.with(|l| *l.borrow_mut() = format!("{msg}{at}"));
            } else {
                default(info);
            }
        }));
    });
}

/// A readable dump of an input: the text when it is mostly printable, else a hex dump of its
/// first 512 bytes.
pub fn dump(bytes: &[u8]) -> String {
    let printable = bytes
        .iter()
        .filter(|&&b| b == b'\n' || b == b'\t' || (0x20..0x7F).contains(&b))
        .count();
    if !bytes.is_empty() && printable * 10 >= bytes.len() * 9 {
        let text = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
        let more = if bytes.len() > 4096 { "\n    …" } else { "" };
        return format!("    {} bytes of text:\n{text}{more}", bytes.len());
    }
    let mut out = format!("    {} bytes, hex of the first 512:", bytes.len());
    for (i, row) in bytes[..bytes.len().min(512)].chunks(16).enumerate() {
        out.push_str(&format!("\n    {:06x} ", 16 * i));
        for b in row {
            out.push_str(&format!(" {b:02x}"));
        }
    }
    out
}

/// What the watchdog watches: the start of the current input and how to name it.
type Current = Arc<Mutex<Option<(Instant, String, PathBuf)>>>;

/// Aborts the process when the current input runs past `limit`.
fn watchdog(
    current: Current,
    done: Arc<AtomicBool>,
    limit: Duration,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        while !done.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(100));
            let guard = current.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((start, what, input)) = guard.as_ref()
                && start.elapsed() > limit
            {
                use std::io::Write;
                let _ = std::io::stderr().write_all(
                    format!(
                        "\nfuzz: {what} still running after {:.0} s (a hang); input kept at {}\n",
                        limit.as_secs_f64(),
                        input.display()
                    )
                    .as_bytes(),
                );
                std::process::abort();
            }
        }
    })
}

/// Runs the pass of `reader` with its scratch files under `scratch`.
pub fn run(reader: Reader, settings: &Settings, scratch: &Path) -> Report {
    install_panic_hook();
    let start = Instant::now();
    let target = Target::new(reader, &scratch.join(reader.name()))
        .unwrap_or_else(|e| panic!("cannot set up the reader: {e}"));
    let corpus = reader
        .corpus()
        .unwrap_or_else(|e| panic!("{}: no corpus: {e}", reader.corpus_dir().display()));
    assert!(
        !corpus.is_empty(),
        "{}: the corpus is empty",
        reader.corpus_dir().display()
    );
    let failures_dir = crate::target_dir().join("fuzz-failures");
    let ext = Path::new(reader.input_name())
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("bin");
    let mut report = Report {
        reader,
        inputs: 0,
        accepted: 0,
        rejected: 0,
        caught_inside: 0,
        caught_examples: Vec::new(),
        slowest: (Duration::ZERO, String::new()),
        seconds: 0.0,
        failures: Vec::new(),
    };
    let current: Current = Arc::new(Mutex::new(None));
    let done = Arc::new(AtomicBool::new(false));
    let dog = watchdog(current.clone(), done.clone(), settings.hang_limit);

    let mut check = |case: String, bytes: &[u8], must_accept: bool| {
        let keep_as = failures_dir.join(format!("{}-{case}.{ext}", reader.name()));
        let what = format!("{} case {case}", reader.name());
        crate::alloc::set_context(what.clone(), target.input().to_path_buf(), keep_as.clone());
        *current.lock().unwrap_or_else(|e| e.into_inner()) =
            Some((Instant::now(), what, target.input().to_path_buf()));
        let panics_before = PANICS.with(|p| p.get());
        IN_READ.with(|r| r.set(true));
        let t0 = Instant::now();
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| target.read(bytes)));
        let took = t0.elapsed();
        IN_READ.with(|r| r.set(false));
        *current.lock().unwrap_or_else(|e| e.into_inner()) = None;
        crate::alloc::clear_context();
        report.inputs += 1;
        if took > report.slowest.0 {
            report.slowest = (took, case.clone());
        }
        let problem = match result {
            Err(_) => Some(Problem::Panic(LAST_PANIC.with(|l| l.borrow().clone()))),
            Ok(r) => {
                if PANICS.with(|p| p.get()) > panics_before {
                    report.caught_inside += 1;
                    if report.caught_examples.len() < 3 {
                        let msg = LAST_PANIC.with(|l| l.borrow().clone());
                        report.caught_examples.push((case.clone(), msg));
                    }
                }
                match r {
                    Ok(()) => {
                        report.accepted += 1;
                        None
                    }
                    Err(msg) => {
                        report.rejected += 1;
                        if must_accept {
                            Some(Problem::CorpusRejected(msg))
                        } else if !target.names_input(&msg) {
                            Some(Problem::Unnamed(msg))
                        } else {
                            None
                        }
                    }
                }
            }
        };
        let problem = problem.or((took > settings.time_limit).then_some(Problem::Slow(took)));
        if let Some(problem) = problem {
            let _ = std::fs::create_dir_all(&failures_dir);
            let _ = std::fs::write(&keep_as, bytes);
            report.failures.push(Failure {
                case,
                problem,
                saved: keep_as,
                dump: dump(bytes),
            });
        }
    };

    if settings.first_case == 0 {
        for (path, bytes) in &corpus {
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
            check(format!("corpus-{}", name.unwrap_or_default()), bytes, true);
        }
    }
    let seeds: Vec<Vec<u8>> = corpus.into_iter().map(|(_, b)| b).collect();
    let mutator = Mutator::new(&seeds, reader.layout());
    for case in settings.first_case..settings.first_case + settings.inputs {
        let bytes = mutator.input(case_seed(reader, case));
        check(case.to_string(), &bytes, false);
    }
    done.store(true, Ordering::Relaxed);
    let _ = dog.join();
    report.seconds = start.elapsed().as_secs_f64();
    report
}
