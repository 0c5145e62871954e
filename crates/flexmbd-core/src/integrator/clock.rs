//! The end time and the output times of a run, on which its steps land.

use crate::integrator::settings::{Integrator, SimulationSettings, StepControl};
use crate::output::Event;

/// The "step size" event of a run whose nominal step is longer than its output interval: its
/// steps end on the output times, so none is longer than the interval and the step size asked
/// for has no effect (a study varying it would find every case alike). None where the steps
/// are fine as asked, and where the step size is only the first step of an error control.
/// `time`: the run's start.
pub(crate) fn step_above_output_interval(settings: &SimulationSettings, time: f64) -> Option<Event> {
    let dt = settings.output_interval?;
    let nominal = match &settings.integrator {
        Integrator::GeneralizedAlpha => !matches!(settings.step_control, StepControl::Error { .. }),
        Integrator::Explicit(explicit) => !explicit.method.adaptive(),
    };
    let h = settings.step_size;
    (nominal && h > dt * (1.0 + 1e-9)).then(|| Event {
        time,
        kind: "step size".to_string(),
        message: format!(
            "the step size {h:e} s is longer than the output interval {dt:e} s: the steps end on \
             the output times, so they are {dt:e} s (a longer output interval, or none, steps \
             at {h:e} s)"
        ),
    })
}

/// The end time and the output times of a run: steps are shortened to land on them, and
/// `due` says whether an accepted step ended on one (and moves on to the next).
pub(crate) struct OutputClock {
    start: f64,
    interval: Option<f64>,
    index: usize,
    next: Option<f64>,
    /// The steps of one size since a time: (that time, the step size, how many), so that the
    /// end of the k-th step is `anchor + k h`, one rounding, not k summed ones.
    run: Option<(f64, f64, u64)>,
    /// End time of the run.
    pub end: f64,
    /// Time tolerance of "landed on".
    pub eps: f64,
}

impl OutputClock {
    /// The clock of a run from `from` (the start time, or later when the run continues
    /// another): the output times stay on the grid from the start time.
    pub(crate) fn new(settings: &SimulationSettings, from: f64) -> Self {
        let start = settings.start_time;
        let eps = 1e-12 * (1.0 + settings.end_time.abs());
        let mut index = 1;
        if let Some(dt) = settings.output_interval {
            // The first output time after `from` (at most a step of round-off away from the
            // estimate; the settings keep dt above the minimum step size).
            index = (((from - start) / dt).floor() as usize).max(1);
            for _ in 0..4 {
                if start + dt * index as f64 > from + eps {
                    break;
                }
                index += 1;
            }
        }
        OutputClock {
            start,
            interval: settings.output_interval,
            index,
            next: settings.output_interval.map(|dt| start + dt * index as f64),
            run: None,
            end: settings.end_time,
            eps,
        }
    }

    /// The end of an accepted step of size `h` from `from`, landed (see `land`). Consecutive
    /// steps of one size end at `anchor + k h`: summing them one by one drifts by a rounding
    /// per step (at h = 1e-6 some 3e-12 s over an output interval of 0.1 s, beyond the time
    /// tolerance), and the step before an output time then stopped that much short of it,
    /// leaving a step of a few 1e-12 s, whose Newton matrix (scaled by 1 / h^2) is garbage.
    pub(crate) fn finish_step(&mut self, from: f64, h: f64) -> f64 {
        let (anchor, count) = match self.run {
            Some((anchor, size, count)) if size == h && anchor + size * count as f64 == from => {
                (anchor, count + 1)
            }
            _ => (from, 1),
        };
        let time = anchor + h * count as f64;
        let landed = self.land(time);
        self.run = if landed == time { Some((anchor, h, count)) } else { None };
        landed
    }

    /// Whether the run has not reached its end at `time`.
    pub(crate) fn running(&self, time: f64) -> bool {
        time < self.end - self.eps
    }

    /// The step from `time` of at most `h` that lands exactly on the end and the next output.
    /// A target within the time tolerance of a whole step `h` is reached by `h` itself (and
    /// `land` puts the step's end on it): shortening the step by the round-off of the summed
    /// times would give it a step size of its own, and the matrices factorized for `h` (kept
    /// from step to step) would be factorized again.
    pub(crate) fn step(&self, time: f64, h: f64) -> f64 {
        let mut h_try = h;
        for target in std::iter::once(self.end).chain(self.next) {
            let to_target = target - time;
            if to_target < h_try + self.eps && (to_target - h).abs() > self.eps {
                h_try = to_target;
            }
        }
        h_try
    }

    /// `time` (the end of an accepted step) put on the end or the next output time when it is
    /// within the time tolerance of it.
    pub(crate) fn land(&self, time: f64) -> f64 {
        std::iter::once(self.end).chain(self.next).find(|t| (time - t).abs() <= self.eps).unwrap_or(time)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::settings::{ExplicitMethod, ExplicitSettings};

    #[test]
    fn a_continued_run_keeps_the_output_times_of_the_start_time() {
        let mut settings = SimulationSettings::new(1.0, 1e-3);
        settings.start_time = 0.25;
        settings.output_interval = Some(0.1);
        // From the start: 0.35, 0.45, ...
        let clock = OutputClock::new(&settings, 0.25);
        assert_eq!(clock.next, Some(0.25 + 0.1));
        // From between two output times, and from (within round-off of) one: the next one.
        for (from, index) in [(0.5731, 4), (0.65, 5), (0.65 - 1e-15, 5), (0.65 + 1e-15, 5), (0.9, 7)] {
            let clock = OutputClock::new(&settings, from);
            assert_eq!(clock.index, index, "from {from}");
            assert_eq!(clock.next, Some(0.25 + 0.1 * index as f64));
            assert!(clock.step(from, 1.0) > 0.0);
        }
        // Without an output interval every step is recorded.
        settings.output_interval = None;
        let mut clock = OutputClock::new(&settings, 0.5731);
        assert!(clock.due(0.6));
    }

    /// Settings of a run to `end` with step `h` and outputs every `dt`.
    fn landing_settings(h: f64, dt: f64, end: f64) -> SimulationSettings {
        let mut settings = SimulationSettings::new(end, h);
        settings.output_interval = Some(dt);
        settings
    }

    /// The steps of a run of `settings` as the time loop takes them, the end of each from
    /// `finish` (clock, start, step): every step must be the step size and every output land
    /// on the grid. Returns (steps, outputs, end time).
    fn landed_run(
        settings: &SimulationSettings,
        finish: impl Fn(&mut OutputClock, f64, f64) -> f64,
    ) -> (usize, usize, f64) {
        let (h, dt) = (settings.step_size, settings.output_interval.expect("an output interval"));
        let mut clock = OutputClock::new(settings, 0.0);
        let (mut time, mut steps, mut outputs) = (0.0, 0usize, 0usize);
        while clock.running(time) {
            let h_try = clock.step(time, h);
            assert_eq!(h_try, h, "step {steps} from t = {time}");
            time = finish(&mut clock, time, h_try);
            steps += 1;
            if clock.due(time) {
                outputs += 1;
                assert_eq!(time, dt * outputs as f64, "output {outputs}");
            }
        }
        (steps, outputs, time)
    }

    #[test]
    fn steps_of_a_long_run_keep_their_size_and_land_on_every_output_time() {
        // Summed step times drift from the output grid by round-off (at t = 10 s some 1e-14 s,
        // 1e-11 of h): a step shortened by it would have a step size of its own, refactorizing
        // the matrices kept for h. The steps keep h and land exactly on the grid and the end.
        let (h, dt, end) = (1e-3, 1e-2, 20.0);
        let settings = landing_settings(h, dt, end);
        let run = landed_run(&settings, |clock, time, h| clock.land(time + h));
        assert_eq!(run, (20_000, 2_000, end));
        // A step still shortens to an output time it would pass by more than round-off.
        let clock = OutputClock::new(&settings, 0.0);
        assert_eq!(clock.step(0.0, 0.015), dt);
        let clock = OutputClock::new(&settings, 19.995);
        assert_eq!(clock.step(19.995, 0.01), end - 19.995);
    }

    #[test]
    fn tiny_steps_land_on_every_output_time_without_slivers() {
        // h = 1e-6: half a million steps, 1e5 between output times. Summed one by one, the
        // times drifted by up to some 3e-12 s from the grid (beyond the tolerance of 1.5e-12),
        // and the step before an output time stopped short of it, leaving a step of 2.7e-12 s
        // (the four-bar of the examples then ended in non-finite values at t = 0.400001).
        let (h, dt, end) = (1e-6, 0.1, 0.5);
        let settings = landing_settings(h, dt, end);
        let run = landed_run(&settings, |clock, time, h| clock.finish_step(time, h));
        assert_eq!(run, (500_000, 5, end));
        // The same times summed one by one: a sliver before some output time.
        let mut clock = OutputClock::new(&settings, 0.0);
        let (mut time, mut smallest) = (0.0f64, h);
        while clock.running(time) {
            let h_try = clock.step(time, h);
            smallest = smallest.min(h_try);
            time = clock.land(time + h_try);
            clock.due(time);
        }
        assert!(smallest < 1e-5 * h, "smallest {smallest}"); // 2.7e-12 s
                                                             // A step of another size (shortened to an output, or after a rejection) starts a new
                                                             // run of steps from its end.
        let mut clock = OutputClock::new(&settings, 0.0);
        assert_eq!(clock.finish_step(0.0, 0.03), 0.03);
        assert_eq!(clock.finish_step(0.03, 0.03), 0.06);
        assert_eq!(clock.finish_step(0.06, 0.02), 0.08);
        assert_eq!(clock.finish_step(0.08, 0.02), 0.1);
        // A step that does not start where the last one ended (a continued run) too.
        assert_eq!(clock.finish_step(0.25, 0.02), 0.27);
        assert_eq!(clock.run, Some((0.25, 0.02, 1)));
    }

    #[test]
    fn a_nominal_step_longer_than_the_output_interval_is_an_event() {
        let mut settings = SimulationSettings::new(1.0, 2e-3);
        settings.output_interval = Some(1e-3);
        let event = step_above_output_interval(&settings, 0.5).expect("an event");
        assert_eq!((event.time, event.kind.as_str()), (0.5, "step size"));
        assert!(event.message.starts_with("the step size 2e-3 s is longer than the output interval 1e-3 s"));
        // And the clock cuts every step to the interval.
        let clock = OutputClock::new(&settings, 0.5);
        assert!((clock.step(0.5, 2e-3) - 1e-3).abs() < 1e-15);
        // Not at or below the interval (round-off of a step given as the interval included),
        // nor without an output interval.
        for (h, dt) in
            [(1e-3, Some(1e-3)), (1e-3 * (1.0 + 1e-12), Some(1e-3)), (5e-4, Some(1e-3)), (2e-3, None)]
        {
            settings.step_size = h;
            settings.output_interval = dt;
            assert!(step_above_output_interval(&settings, 0.0).is_none(), "h {h}, dt {dt:?}");
        }
        // Where the step size is only the first step of an error control: no event. Newton's
        // control (steps back to the nominal one) and Runge-Kutta 4 (fixed): an event.
        settings.step_size = 2e-3;
        settings.output_interval = Some(1e-3);
        settings.step_control = StepControl::Error { relative_tolerance: 1e-6, absolute_tolerance: 1e-8 };
        assert!(step_above_output_interval(&settings, 0.0).is_none());
        settings.step_control = StepControl::Newton;
        assert!(step_above_output_interval(&settings, 0.0).is_some());
        for (method, event) in
            [(ExplicitMethod::Rk4, true), (ExplicitMethod::Dopri5, false), (ExplicitMethod::TrBdf2, false)]
        {
            settings.integrator = Integrator::Explicit(ExplicitSettings { method, ..Default::default() });
            assert_eq!(step_above_output_interval(&settings, 0.0).is_some(), event, "{method:?}");
        }
    }
}
