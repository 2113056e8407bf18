//! Progress for a person: a live bar on a terminal, and in a log file (the standard error of
//! a batch job) a timestamped line every few minutes, so that the log of a week-long run on a
//! cluster shows how far it got and when. `CLV_LOG_SECONDS` sets the interval of those lines
//! (default 300 s; 0 writes every update, at most one a second).

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle, TermLike};
use std::io::{IsTerminal, Write};
use std::sync::Mutex;
use std::time::{Duration, Instant, SystemTime};

/// A progress bar of steps, `what` its label.
pub fn steps(what: &str) -> ProgressBar {
    bar(what, "{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} steps, {per_sec} ({eta} left)", "{msg}: step {pos} of {len} ({percent}%), {rate} steps a second, {elapsed} elapsed, about {eta} left")
}

/// A counter of frames whose total is not known (a stream).
pub fn frames(what: &str) -> ProgressBar {
    bar(what, "{msg} [{elapsed_precise}] {pos} frames, {per_sec}", "{msg}: {pos} frames, {rate} frames a second, {elapsed} elapsed")
}

/// Bars drawn together (one line each).
pub fn multi() -> MultiProgress {
    MultiProgress::with_draw_target(target())
}

fn bar(what: &str, on_terminal: &str, in_log: &str) -> ProgressBar {
    // Drawn only from the caller's first update on (with its length known).
    let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::hidden());
    let template = if logging() { in_log } else { on_terminal };
    let style = ProgressStyle::with_template(template).expect("static template");
    bar.set_style(style.with_key("rate", |state: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
        let _ = write!(w, "{:.1}", state.per_sec());
    }));
    bar.set_message(what.to_string());
    bar.set_draw_target(target());
    bar
}

fn logging() -> bool {
    !std::io::stderr().is_terminal()
}

fn target() -> ProgressDrawTarget {
    if !logging() {
        return ProgressDrawTarget::stderr();
    }
    ProgressDrawTarget::term_like_with_hz(Box::new(LogLines::new(log_interval())), 1)
}

/// `CLV_LOG_SECONDS`, or five minutes (a value that is not a number of seconds is said so, once).
fn log_interval() -> Duration {
    static INTERVAL: std::sync::OnceLock<Duration> = std::sync::OnceLock::new();
    *INTERVAL.get_or_init(|| {
        let seconds = match std::env::var("CLV_LOG_SECONDS") {
            Err(_) => 300,
            Ok(v) => v.trim().parse().unwrap_or_else(|_| {
                crate::note!("clv: warning: CLV_LOG_SECONDS={v:?} is not a whole number of seconds; logging progress every 300 s");
                300
            }),
        };
        Duration::from_secs(seconds)
    })
}

/// A [`TermLike`] that turns the bars' redraws into log lines, one redraw in `interval`.
#[derive(Debug)]
struct LogLines {
    interval: Duration,
    state: Mutex<LogState>,
}

#[derive(Debug)]
struct LogState {
    /// The lines of the redraw in progress.
    lines: Vec<String>,
    /// When the last lines were written (the start counts as one).
    last: Instant,
}

/// Wide enough that no line wraps: indicatif pads every line to this width with blanks,
/// which mark the end of a line here.
const WIDTH: u16 = 1000;

impl LogLines {
    fn new(interval: Duration) -> Self {
        LogLines { interval, state: Mutex::new(LogState { lines: Vec::new(), last: Instant::now() }) }
    }

    fn push(&self, s: &str) {
        let text = s.trim_matches(['\r', '\n']);
        if !text.trim().is_empty() {
            self.state.lock().unwrap_or_else(|e| e.into_inner()).lines.push(text.trim_end().to_string());
        }
    }
}

impl TermLike for LogLines {
    fn width(&self) -> u16 {
        WIDTH
    }
    fn height(&self) -> u16 {
        100
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
        self.push(s);
        Ok(())
    }
    fn write_str(&self, s: &str) -> std::io::Result<()> {
        self.push(s);
        Ok(())
    }
    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }
    fn flush(&self) -> std::io::Result<()> {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let lines = std::mem::take(&mut state.lines);
        if lines.is_empty() || state.last.elapsed() < self.interval {
            return Ok(());
        }
        state.last = Instant::now();
        let stamp = utc(SystemTime::now());
        let mut err = std::io::stderr().lock();
        for line in lines {
            writeln!(err, "clv: {stamp} {line}")?;
        }
        Ok(())
    }
}

/// `t` as an ISO 8601 UTC time to the second, e.g. 2026-11-24T06:30:00Z.
fn utc(t: SystemTime) -> String {
    let secs = t.duration_since(SystemTime::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rest) = (secs / 86400, secs % 86400);
    // Days since 1970-01-01 to a civil date (H. Hinnant's algorithm, proleptic Gregorian).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z", rest / 3600, rest % 3600 / 60, rest % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_dates() {
        let at = |s: u64| utc(SystemTime::UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "1970-01-01T00:00:00Z");
        assert_eq!(at(951_782_400), "2000-02-29T00:00:00Z", "a leap day");
        assert_eq!(at(1_795_500_000), "2026-11-24T06:00:00Z");
        assert_eq!(at(4_107_542_399), "2100-02-28T23:59:59Z", "2100 is no leap year");
    }

    /// A redraw becomes one log line per bar, at most one redraw per interval.
    #[test]
    fn redraws_become_lines_once_per_interval() {
        let log = LogLines::new(Duration::from_secs(3600));
        log.write_str("forward: step 5 of 10").unwrap();
        log.write_str(&" ".repeat(900)).unwrap();
        log.flush().unwrap();
        assert!(log.state.lock().unwrap().lines.is_empty(), "a redraw within the interval is dropped");
        let log = LogLines::new(Duration::ZERO);
        log.write_str("\rrecompute: step 1 of 2").unwrap();
        log.write_str("   ").unwrap();
        log.write_str("sweep: step 0 of 2").unwrap();
        assert_eq!(log.state.lock().unwrap().lines, ["recompute: step 1 of 2", "sweep: step 0 of 2"]);
        log.flush().unwrap();
        assert!(log.state.lock().unwrap().lines.is_empty());
    }
}
