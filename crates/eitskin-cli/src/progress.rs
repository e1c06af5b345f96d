//! Progress of the long commands (`study`, `learn`, `robot-presses`, `sensitivity`) on stderr,
//! as each stage goes: where stderr is a terminal a bar with the time spent and left, else a
//! line per stage, so a log shows where the time went.

use std::time::Instant;

/// Progress on stderr: a bar per stage, with the time spent and an estimate of the
/// time left (hidden where stderr is not a terminal, where a line per stage is printed instead).
#[derive(Default)]
pub struct Bars {
    stage: String,
    bar: Option<indicatif::ProgressBar>,
    start: Option<Instant>,
}

impl Bars {
    /// Stage `stage` has done `done` of `all` steps. A stage written `STAGE · STEP` keeps one
    /// bar for `STAGE`, naming the step it is on.
    pub fn update(&mut self, stage: &str, done: usize, all: usize) {
        let start = *self.start.get_or_insert_with(Instant::now);
        let key = stage.split(" · ").next().unwrap_or(stage);
        if key != self.stage {
            self.finish();
            self.stage = key.to_string();
            let bar = indicatif::ProgressBar::new(all as u64);
            let style = indicatif::ProgressStyle::with_template(
                "{msg:50} {bar:30} {pos}/{len} [{elapsed} elapsed, {eta} left]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
            bar.set_style(style);
            bar.set_message(stage.to_string());
            if bar.is_hidden() {
                eprintln!("[{:>6.1} s] {key}", start.elapsed().as_secs_f64());
            }
            self.bar = Some(bar);
        }
        if let Some(bar) = &self.bar {
            bar.set_message(stage.to_string());
            bar.set_length(all as u64);
            bar.set_position(done as u64);
        }
    }

    /// Ends the stage's bar, leaving it on the screen.
    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish();
        }
    }
}
