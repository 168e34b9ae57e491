//! Progress display: indicatif bars on a terminal, plain timestamped lines otherwise (overnight logs).

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Instant;

/// Progress of a multi-stage job: an outer bar (generations, jobs) and an inner bar (units).
pub struct Progress {
    bars: Option<(MultiProgress, ProgressBar, ProgressBar)>,
    started: Instant,
    inner: Mutex<(u64, u64, Instant)>,
    quiet: bool,
}

fn stamp() -> String {
    crate::store::now_utc().1
}

impl Progress {
    /// Bars when stderr is a terminal, lines otherwise; `quiet` prints nothing.
    pub fn new(outer_label: &str, outer_total: u64, quiet: bool) -> Self {
        let bars = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let multi = MultiProgress::with_draw_target(ProgressDrawTarget::stderr());
            let outer = multi.add(ProgressBar::new(outer_total));
            outer.set_style(
                ProgressStyle::with_template(&format!(
                    "{outer_label:>11} [{{bar:30}}] {{pos}}/{{len}}  {{elapsed_precise}}"
                ))
                .expect("valid template")
                .progress_chars("=> "),
            );
            let inner = multi.add(ProgressBar::new(0));
            inner.set_style(
                ProgressStyle::with_template("{prefix:>11} [{bar:30}] {pos}/{len}  {msg}")
                    .expect("valid template")
                    .progress_chars("=> "),
            );
            (multi, outer, inner)
        });
        Progress { bars, started: Instant::now(), inner: Mutex::new((0, 0, Instant::now())), quiet }
    }

    /// Starts a stage of `total` units (e.g. a generation; more can be added).
    pub fn start_stage(&self, name: &str, total: u64) {
        *self.inner.lock().expect("progress lock") = (0, total, Instant::now());
        if let Some((_, _, inner)) = &self.bars {
            inner.set_prefix(name.to_string());
            inner.set_length(total);
            inner.set_position(0);
            inner.reset_eta();
        } else if !self.quiet && total > 0 {
            eprintln!("{} {name}: {total} units to run", stamp());
        }
    }

    /// Adds `n` units to the current stage (work found as the stage goes, e.g. a round of datasets),
    /// saying so in the plain log if `say` (units opened one by one as others finish are not said,
    /// one line each would drown the log; the every-10-units line shows the growing total).
    pub fn add_to_stage(&self, n: u64, say: bool) {
        let total = {
            let mut g = self.inner.lock().expect("progress lock");
            g.1 += n;
            g.1
        };
        if let Some((_, _, inner)) = &self.bars {
            inner.set_length(total);
        } else if !self.quiet && say && n > 0 {
            eprintln!("{}   {n} units to run ({total} in this stage)", stamp());
        }
    }

    /// One unit of the current stage is done; `note` (e.g. an ETA) is shown beside the bar, and in
    /// the plain log every 10 units.
    pub fn unit_done(&self, note: &str) {
        let (done, total, since) = {
            let mut g = self.inner.lock().expect("progress lock");
            g.0 += 1;
            *g
        };
        let per = since.elapsed().as_secs_f64() / done as f64;
        let note = if note.is_empty() { format!("stage ≈ {}", human(per * total as f64)) } else { note.to_string() };
        if let Some((_, _, inner)) = &self.bars {
            inner.inc(1);
            inner.set_message(format!("{per:.1} s/unit · {note}"));
        } else if !self.quiet && (done == 1 || done == total || done.is_multiple_of(10)) {
            eprintln!("{}   {done}/{total} units ({per:.1} s/unit; {note})", stamp());
        }
    }

    /// A stage finished; advances the outer bar.
    pub fn stage_done(&self) {
        if let Some((_, outer, _)) = &self.bars {
            outer.inc(1);
        }
    }

    /// Prints a line above the bars (or timestamped, without bars).
    pub fn line(&self, text: &str) {
        match &self.bars {
            Some((multi, _, _)) => {
                let _ = multi.println(text);
            }
            None if !self.quiet => eprintln!("{} {text}", stamp()),
            None => {}
        }
    }

    /// Removes the bars.
    pub fn finish(&self) {
        if let Some((multi, outer, inner)) = &self.bars {
            inner.finish_and_clear();
            outer.finish_and_clear();
            let _ = multi.clear();
        }
    }

    /// Seconds since creation.
    pub fn elapsed(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }
}

/// A duration for humans: `42 s`, `3.5 min`, `2.1 h`.
pub fn human(seconds: f64) -> String {
    if seconds < 90.0 {
        format!("{seconds:.0} s")
    } else if seconds < 5400.0 {
        format!("{:.1} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}
