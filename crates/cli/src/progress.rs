//! Progress of long counted work: a bar on a terminal, a plain line at most every 10 s in
//! pipes and logs (where a bar cannot draw).

use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// Longest silence of a long command when stderr is not a terminal (every command's
/// plain progress lines share it).
pub const PLAIN_EVERY: Duration = Duration::from_secs(10);

/// A counter of `total` units with rate and ETA.
pub struct Counter {
    bar: Option<ProgressBar>,
    what: String,
    unit: &'static str,
    total: u64,
    started: Instant,
    last_line: Instant,
    done: u64,
}

impl Counter {
    /// Starts counting `total` `unit`s of `what`.
    pub fn new(total: u64, what: &str, unit: &'static str) -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let bar = ProgressBar::new(total);
            bar.set_style(
                ProgressStyle::with_template(&format!(
                    "{{msg}} [{{bar:30}}] {{pos}}/{{len}} {unit} {{per_sec}} ETA {{eta}}"
                ))
                .expect("a valid template")
                .progress_chars("=> "),
            );
            bar.set_message(what.to_owned());
            bar
        });
        Self {
            bar,
            what: what.to_owned(),
            unit,
            total,
            started: Instant::now(),
            last_line: Instant::now(),
            done: 0,
        }
    }

    /// `done` units are finished. Progress never goes back, and the line of the last unit
    /// is printed once, however often it is reported.
    pub fn set(&mut self, done: u64) {
        let done = done.min(self.total);
        if done <= self.done && done > 0 {
            return;
        }
        self.done = done;
        match &self.bar {
            Some(bar) => bar.set_position(done),
            None if self.last_line.elapsed() >= PLAIN_EVERY || done == self.total => {
                self.last_line = Instant::now();
                let secs = self.started.elapsed().as_secs_f64().max(1e-9);
                let rate = done as f64 / secs;
                let eta = (self.total.saturating_sub(done)) as f64 / rate.max(1e-9);
                eprintln!(
                    "{}: {done}/{} {} ({rate:.0}/s, ETA {eta:.0} s)",
                    self.what, self.total, self.unit
                );
            }
            None => {}
        }
    }

    /// Removes the bar.
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
    fn progress_never_goes_back_and_the_end_is_reached_once() {
        let mut counter = Counter::new(10, "test", "steps");
        counter.set(4);
        counter.set(2);
        assert_eq!(counter.done, 4);
        counter.set(10);
        let printed_at = counter.last_line;
        counter.set(3);
        counter.set(99);
        assert_eq!((counter.done, counter.last_line), (10, printed_at));
    }
}
