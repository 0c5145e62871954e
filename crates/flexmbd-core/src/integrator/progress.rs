//! What a running simulation reports to its observer after every accepted step: the time, the
//! step and the records so far (for results written during the run).

use std::cell::Cell;

use crate::integrator::redundancy::Reduction;
use crate::integrator::settings::RedundancyHandling;
use crate::output::Output;
use crate::system::{Model, State};

/// Progress reported to the observer after every accepted step.
#[derive(Clone, Copy)]
pub struct Progress<'a> {
    /// Time reached (s).
    pub time: f64,
    /// Last step size (s).
    pub step_size: f64,
    /// Newton iterations of the last step.
    pub newton_iterations: usize,
    /// Accepted steps so far.
    pub steps: usize,
    /// The state reached (of the model the integrator runs: without removed redundant rows,
    /// its multipliers are those of the rows kept).
    pub state: &'a State,
    /// The records so far, for results written during the run.
    pub records: Records<'a>,
    /// Set by the observer to the number of records (from the first one held) it stored
    /// elsewhere and that the run may drop ([`Output::release_front`]); 0 keeps them all.
    pub release: &'a Cell<usize>,
}

/// The records of a run in progress, as they will be in its final output.
#[derive(Clone, Copy)]
pub struct Records<'a> {
    output: &'a Output,
    /// The model of the run, the reduction to expand the records with, and its handling.
    reduction: Option<(&'a Model, &'a Reduction, RedundancyHandling)>,
    /// The records held of the run's earlier segments (with other rows removed), expanded:
    /// they come before `output`'s.
    earlier: Option<&'a Output>,
}

impl<'a> Records<'a> {
    pub(crate) fn new(output: &'a Output) -> Self {
        Records { output, reduction: None, earlier: None }
    }

    /// The same records expanded by `reduction` (of `model`) to the rows of the model before
    /// its redundant constraints were removed.
    pub(crate) fn expanded(
        self,
        model: &'a Model,
        reduction: &'a Reduction,
        handling: RedundancyHandling,
    ) -> Self {
        Records { reduction: Some((model, reduction, handling)), ..self }
    }

    /// The same records after those held of the run's `earlier` segments.
    pub(crate) fn after(self, earlier: &'a Output) -> Self {
        Records { earlier: Some(earlier), ..self }
    }

    /// Number of records so far.
    pub fn len(&self) -> usize {
        self.output.len() + self.earlier.map_or(0, Output::len)
    }

    /// True if nothing was recorded yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The records from index `from` on, with the statistics and events so far, in the layout
    /// of the final output (the multipliers of removed redundant rows restored).
    pub fn since(&self, from: usize) -> Output {
        let held_earlier = self.earlier.map_or(0, Output::len);
        let current_from = from.saturating_sub(held_earlier);
        let current = match self.reduction {
            None => self.output.since(current_from),
            Some((model, reduction, handling)) => {
                reduction.expand_since(model, self.output, current_from, handling)
            }
        };
        match self.earlier {
            None => current,
            Some(earlier) => {
                let from = from.min(self.len());
                let mut out = earlier.since(from);
                out.append(current);
                // Records are released from the earlier segments' first.
                out.released = earlier.released + self.output.released + from;
                out
            }
        }
    }
}
