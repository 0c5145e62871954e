//! The end time and the output times of a run, on which its steps land.

use crate::integrator::settings::SimulationSettings;

/// The end time and the output times of a run: steps are shortened to land on them, and
/// `due` says whether an accepted step ended on one (and moves on to the next).
pub(crate) struct OutputClock {
    start: f64,
    interval: Option<f64>,
    index: usize,
    next: Option<f64>,
    /// End time of the run.
    pub end: f64,
    /// Time tolerance of "landed on".
    pub eps: f64,
}

impl OutputClock {
    pub(crate) fn new(settings: &SimulationSettings) -> Self {
        OutputClock {
            start: settings.start_time,
            interval: settings.output_interval,
            index: 1,
            next: settings.output_interval.map(|dt| settings.start_time + dt),
            end: settings.end_time,
            eps: 1e-12 * (1.0 + settings.end_time.abs()),
        }
    }

    /// Whether the run has not reached its end at `time`.
    pub(crate) fn running(&self, time: f64) -> bool {
        time < self.end - self.eps
    }

    /// The step from `time` of at most `h` that lands exactly on the end and the next output.
    pub(crate) fn step(&self, time: f64, h: f64) -> f64 {
        let mut h_try = h.min(self.end - time);
        if let Some(t_out) = self.next {
            if t_out - time < h_try + self.eps {
                h_try = t_out - time;
            }
        }
        h_try
    }

    /// Whether a step that ended at `time` is to be recorded; advances to the next output.
    pub(crate) fn due(&mut self, time: f64) -> bool {
        let at_end = time >= self.end - self.eps;
        let at_output = match self.next {
            None => true,
            Some(t_out) => (time - t_out).abs() <= self.eps || at_end,
        };
        if at_output {
            if let Some(dt) = self.interval {
                self.index += 1;
                self.next = if at_end { None } else { Some(self.start + dt * self.index as f64) };
            }
        }
        at_output
    }
}
