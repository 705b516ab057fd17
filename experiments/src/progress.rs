//! Where progress goes. On a terminal, an `indicatif` bar redrawn in place. Elsewhere (a run
//! under `nohup`, CI, Slurm, or `figures … 2> log`) `indicatif` would draw nothing, and a
//! 37-minute atlas would log nothing between its start and its end; so when stderr is not a
//! terminal the same bar is written as plain lines (`prefix [elapsed] pos/len pct% eta msg`),
//! at most one every [`PROGRESS_ENV`] seconds (default [`DEFAULT_SECONDS`]) over all the
//! process's bars and none in its first interval, so short runs and the test suite's quick runs
//! print nothing. Lines that are results, not progress, go through [`note`] and are never
//! held back.
//! `--no-progress` hides both.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle, TermLike};
use std::io::{IsTerminal, Write};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// Seconds between the plain progress lines written when stderr is not a terminal; `0`
/// writes none.
pub const PROGRESS_ENV: &str = "SCATTERBENCH_PROGRESS_SECONDS";

/// The interval of the plain progress lines when [`PROGRESS_ENV`] is not set.
pub const DEFAULT_SECONDS: u64 = 60;

/// The interval of the plain lines: [`PROGRESS_ENV`], or [`DEFAULT_SECONDS`]; `None` for
/// `0`. A value that is not a whole number of seconds is reported once on stderr and the
/// default used (a progress setting is no reason to refuse a run).
fn log_interval() -> Option<Duration> {
    static EVERY: OnceLock<Option<Duration>> = OnceLock::new();
    *EVERY.get_or_init(|| {
        let secs = match std::env::var(PROGRESS_ENV) {
            Err(_) => DEFAULT_SECONDS,
            Ok(v) => v.trim().parse::<u64>().unwrap_or_else(|_| {
                eprintln!(
                    "warning: {PROGRESS_ENV}={v:?} is not a whole number of seconds; \
                     logging progress every {DEFAULT_SECONDS} s"
                );
                DEFAULT_SECONDS
            }),
        };
        (secs > 0).then(|| Duration::from_secs(secs))
    })
}

/// A bar over `len` steps (a spinner for `None`) labelled `what`, drawn as the module docs
/// say; hidden if `hidden`.
pub fn bar(len: Option<u64>, hidden: bool, what: &str) -> ProgressBar {
    if hidden {
        return ProgressBar::hidden();
    }
    let (target, lines) = if std::io::stderr().is_terminal() {
        (ProgressDrawTarget::stderr(), false)
    } else {
        match log_interval() {
            Some(every) => {
                let t = LogLines::new(every, Sink::Stderr, process_clock());
                (t.target(), true)
            }
            None => return ProgressBar::hidden(),
        }
    };
    let pb = ProgressBar::with_draw_target(len, target);
    if let Ok(style) = ProgressStyle::with_template(template(len.is_some(), lines)) {
        pb.set_style(style);
    }
    pb.set_prefix(what.to_string());
    if len.is_none() {
        pb.enable_steady_tick(Duration::from_millis(250));
    }
    pb
}

/// The bar's template: with a drawn bar on a terminal, with the percentage and estimate in
/// the plain lines; a spinner shows its elapsed time and message.
fn template(counted: bool, lines: bool) -> &'static str {
    match (counted, lines) {
        (true, false) => "{prefix:>18} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}",
        (true, true) => "{prefix} [{elapsed_precise}] {pos}/{len} ({percent}%, eta {eta}) {msg}",
        (false, false) => "{spinner} {prefix} [{elapsed_precise}] {msg}",
        (false, true) => "{prefix} [{elapsed_precise}] {msg}",
    }
}

/// Where the plain lines go.
#[derive(Debug)]
enum Sink {
    Stderr,
    /// Collected (the tests).
    #[cfg(test)]
    Memory(Arc<Mutex<Vec<String>>>),
}

/// A line that belongs to the log, not to the bar (a result as it comes): above the bar on a
/// terminal, else on stderr as it is (a bar's own lines are throttled, these never are).
pub fn note(pb: &ProgressBar, line: &str) {
    if !pb.is_hidden() && std::io::stderr().is_terminal() {
        pb.println(line);
    } else {
        eprintln!("{line}");
    }
}

/// When the last plain line was written (or the first bar made; `None`: write the next one):
/// one clock for the process, so that an experiment with many short bars (one per case) still
/// logs once an interval.
type Clock = Arc<Mutex<Option<Instant>>>;

fn process_clock() -> Clock {
    static CLOCK: OnceLock<Clock> = OnceLock::new();
    Arc::clone(CLOCK.get_or_init(|| Arc::new(Mutex::new(Some(Instant::now())))))
}

/// An `indicatif` terminal that keeps what a draw writes (without its cursor moves, carriage
/// returns and padding) and writes it as one line at the draw's end (`flush`), if the
/// interval has passed on its clock since the last line (or since the clock started).
#[derive(Debug)]
struct LogLines {
    every: Duration,
    sink: Sink,
    frame: Mutex<String>,
    clock: Clock,
}

impl LogLines {
    fn new(every: Duration, sink: Sink, clock: Clock) -> Self {
        Self {
            every,
            sink,
            frame: Mutex::new(String::new()),
            clock,
        }
    }

    /// A draw target over `self`, drawn at most once a second.
    fn target(self) -> ProgressDrawTarget {
        ProgressDrawTarget::term_like_with_hz(Box::new(self), 1)
    }

    fn keep(&self, s: &str) {
        if let Ok(mut f) = self.frame.lock() {
            f.extend(s.chars().filter(|&c| c != '\r'));
        }
    }

    fn emit(&self, line: &str) {
        match &self.sink {
            Sink::Stderr => {
                let mut e = std::io::stderr().lock();
                let _ = writeln!(e, "{line}");
            }
            #[cfg(test)]
            Sink::Memory(v) => {
                if let Ok(mut v) = v.lock() {
                    v.push(line.to_string());
                }
            }
        }
    }
}

impl TermLike for LogLines {
    fn width(&self) -> u16 {
        // Wide, so that `indicatif` never wraps or cuts a line.
        500
    }

    fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }

    fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }

    fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }

    fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }

    fn write_line(&self, s: &str) -> std::io::Result<()> {
        self.keep(s);
        self.keep(" ");
        Ok(())
    }

    fn write_str(&self, s: &str) -> std::io::Result<()> {
        self.keep(s);
        Ok(())
    }

    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }

    fn flush(&self) -> std::io::Result<()> {
        let frame = match self.frame.lock() {
            Ok(mut f) => std::mem::take(&mut *f),
            Err(_) => return Ok(()),
        };
        let line = frame.trim();
        if line.is_empty() {
            return Ok(());
        }
        if let Ok(mut last) = self.clock.lock() {
            if last.is_some_and(|t| t.elapsed() < self.every) {
                return Ok(());
            }
            *last = Some(Instant::now());
        }
        self.emit(line);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collected(every: Duration) -> (LogLines, Arc<Mutex<Vec<String>>>) {
        let v = Arc::new(Mutex::new(Vec::new()));
        let clock = Arc::new(Mutex::new(Some(Instant::now())));
        (LogLines::new(every, Sink::Memory(Arc::clone(&v)), clock), v)
    }

    fn lines(v: &Arc<Mutex<Vec<String>>>) -> Vec<String> {
        v.lock().map(|v| v.clone()).unwrap_or_default()
    }

    /// A draw becomes one line without carriage returns or padding; a draw that only clears
    /// (the end of `finish_and_clear`) writes nothing.
    #[test]
    fn a_draw_is_one_plain_line_and_a_clear_is_none() {
        let (t, v) = collected(Duration::ZERO);
        for s in ["\r", "point_source [00:01:02] 3/10", "          "] {
            t.write_str(s).unwrap();
        }
        t.flush().unwrap();
        t.clear_line().unwrap();
        t.flush().unwrap();
        assert_eq!(lines(&v), ["point_source [00:01:02] 3/10"]);
    }

    /// Within the interval (here an hour) nothing is written, however many draws there are.
    #[test]
    fn nothing_is_written_within_the_interval() {
        let (t, v) = collected(Duration::from_secs(3600));
        for k in 0..5 {
            t.write_str(&format!("x {k}/5")).unwrap();
            t.flush().unwrap();
        }
        assert!(lines(&v).is_empty(), "{:?}", lines(&v));
    }

    /// Bars share one clock: after one bar's line, another's draw within the interval writes
    /// nothing (an experiment of many short bars logs once an interval, not once a bar).
    #[test]
    fn bars_share_the_interval() {
        let hour = Duration::from_secs(3600);
        let clock = Arc::new(Mutex::new(None));
        let v = Arc::new(Mutex::new(Vec::new()));
        let sink = || Sink::Memory(Arc::clone(&v));
        let (a, b) = (
            LogLines::new(hour, sink(), Arc::clone(&clock)),
            LogLines::new(hour, sink(), clock),
        );
        for (t, text) in [(&a, "a 1/2"), (&b, "b 1/2"), (&a, "a 2/2")] {
            t.write_str(text).unwrap();
            t.flush().unwrap();
        }
        assert_eq!(lines(&v), ["a 1/2"]);
    }

    /// Through `indicatif`: a finished bar's last draw is a line with its count and
    /// percentage (the template of the plain lines).
    #[test]
    fn a_bar_writes_its_count_as_a_line() {
        let (t, v) = collected(Duration::ZERO);
        let pb = ProgressBar::with_draw_target(Some(10), t.target());
        pb.set_style(ProgressStyle::with_template(template(true, true)).unwrap());
        pb.set_prefix("atlas");
        pb.set_position(3);
        pb.finish_with_message("done");
        let got = lines(&v);
        let last = got.last().cloned().unwrap_or_default();
        assert!(
            last.starts_with("atlas [") && last.ends_with("10/10 (100%, eta 0s) done"),
            "{got:?}"
        );
    }
}
