//! Progress of long work on stderr, the same way in every command: a bar when stderr is a
//! terminal; otherwise (a log file, a CI job) one status line at most every
//! [`STATUS_EVERY`] (or every `FORMATION_TRACKER_STATUS_SECS` seconds when that variable is
//! set), so that a logged run is never silent for minutes. `--quiet` turns both off; results
//! and errors are printed as before.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Default interval between status lines when stderr is not a terminal.
pub const STATUS_EVERY: Duration = Duration::from_secs(5);

/// The interval between status lines: `FORMATION_TRACKER_STATUS_SECS` (seconds, >= 0) if set
/// and valid, else [`STATUS_EVERY`].
fn status_every() -> Duration {
    std::env::var("FORMATION_TRACKER_STATUS_SECS")
        .ok()
        .and_then(|s| s.trim().parse::<f64>().ok())
        .and_then(|s| Duration::try_from_secs_f64(s).ok())
        .unwrap_or(STATUS_EVERY)
}

static QUIET: AtomicBool = AtomicBool::new(false);

/// Writes one line to stderr and ignores a failure: a closed or full stderr (`2>&-`,
/// `2>/dev/full`) must not turn a run into a panic with exit code 101, as `eprintln!` does
/// (issue #32). Every line the commands print on stderr goes through [`errln!`].
pub fn write_stderr(text: std::fmt::Arguments<'_>) {
    use std::io::Write as _;
    let _ = std::io::stderr().lock().write_fmt(text);
}

/// `eprintln!` that never panics: see [`write_stderr`].
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::cmd::progress::write_stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}
pub(crate) use errln;

/// Sets `--quiet` for the whole run (called once by `main`).
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// Progress of one piece of work counted in `unit`s (frames, scenes).
#[derive(Debug)]
pub struct Progress {
    label: &'static str,
    unit: &'static str,
    bar: Option<indicatif::ProgressBar>,
    /// Without a bar: whether status lines are printed, and when the last one was.
    status: Option<Instant>,
    every: Duration,
    started: Instant,
    done: u64,
    total: Option<u64>,
}

impl Progress {
    /// Progress of `total` (if known) `unit`s, labelled `label` in status lines.
    pub fn new(label: &'static str, unit: &'static str, total: Option<u64>) -> Self {
        let quiet = QUIET.load(Ordering::Relaxed);
        let terminal = std::io::stderr().is_terminal();
        let bar = (!quiet && terminal).then(|| {
            let bar = match total {
                Some(n) => indicatif::ProgressBar::new(n),
                None => indicatif::ProgressBar::new_spinner(),
            };
            let template = format!("{{bar:40}} {{pos}}/{{len}} {unit} {{per_sec}} {{eta}}");
            bar.set_style(
                indicatif::ProgressStyle::with_template(&template)
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            bar
        });
        let now = Instant::now();
        Self {
            label,
            unit,
            bar,
            status: (!quiet && !terminal).then_some(now),
            every: status_every(),
            started: now,
            done: 0,
            total,
        }
    }

    /// Sets the total once it is known.
    pub fn set_total(&mut self, total: u64) {
        self.total = Some(total);
        if let Some(bar) = &self.bar {
            bar.set_length(total);
        }
    }

    /// `done` units are finished.
    pub fn set(&mut self, done: u64) {
        self.done = done;
        if let Some(bar) = &self.bar {
            bar.set_position(done);
        }
        if let Some(last) = self.status
            && last.elapsed() >= self.every
        {
            self.status = Some(Instant::now());
            errln!("{}", self.status_line());
        }
    }

    /// One more unit is finished.
    pub fn inc(&mut self) {
        self.set(self.done + 1);
    }

    /// The status line: `track: 1200/3000 frames after 35 s`.
    fn status_line(&self) -> String {
        let of = self.total.map(|t| format!("/{t}")).unwrap_or_default();
        format!(
            "{}: {}{of} {} after {:.0} s",
            self.label,
            self.done,
            self.unit,
            self.started.elapsed().as_secs_f64()
        )
    }

    /// A message line on stderr, above the bar if there is one.
    pub fn println(&self, message: &str) {
        match &self.bar {
            Some(bar) => bar.println(message),
            None => errln!("{message}"),
        }
    }

    /// Clears the bar.
    pub fn finish(self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_lines_say_what_is_done() {
        let mut p = Progress::new("track", "frames", Some(3000));
        p.done = 1200;
        assert!(
            p.status_line()
                .starts_with("track: 1200/3000 frames after ")
        );
        let mut p = Progress::new("track", "frames", None);
        p.done = 7;
        assert!(p.status_line().starts_with("track: 7 frames after "));
    }
}
