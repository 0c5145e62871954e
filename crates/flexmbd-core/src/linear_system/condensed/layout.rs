//! The layout of a condensed solver, made once per model: the split of the unknowns of the
//! Newton matrix into the elastic coordinates F of the condensed bodies and the rest S, the
//! coupling entries of each body, and the pattern of the reduced (Schur complement) system.

use super::factor::ReducedLu;
use super::{flexible, Block, CondensedSolver};
use crate::body::flexible::REFERENCE_COORDINATES;
use crate::body::is_condensed;
use crate::error::{FlexmbdError, Result};
use crate::linalg::sparse::{PatternBuilder, SparsePattern};
use crate::math::Vec3;
use crate::system::model::Model;
use std::collections::BTreeMap;

/// The entries (local f, value index) of one coupling unknown j: N_{f, j}, then N_{j, f}.
type Coupling = (Vec<(usize, usize)>, Vec<(usize, usize)>);

/// The elastic coordinates of a condensed body: (body index, first global index, n_f).
type ElasticRange = (usize, usize, usize);

/// The unknowns of the Newton matrix split into the condensed ones (F) and the reduced ones (S).
struct Split {
    /// The elastic coordinates of each condensed body, in the order of the bodies.
    ranges: Vec<ElasticRange>,
    /// Global index -> reduced index (usize::MAX for condensed unknowns).
    reduced_of: Vec<usize>,
    /// Reduced index -> global index.
    global_of: Vec<usize>,
}

impl Split {
    /// The split of the unknowns of `model`'s Newton matrix (pattern `model.layout.pattern`).
    fn of(model: &Model) -> Self {
        let mut reduced_of = vec![0usize; model.layout.pattern.n];
        let mut ranges = Vec::new();
        for (bi, body) in model.bodies.iter().enumerate() {
            if is_condensed(&body.kind) {
                let fb = flexible(model, bi);
                let first = body.offset + REFERENCE_COORDINATES;
                for k in first..first + fb.elastic_count {
                    reduced_of[k] = usize::MAX;
                }
                ranges.push((bi, first, fb.elastic_count));
            }
        }
        let mut global_of = Vec::new();
        for (g, r) in reduced_of.iter_mut().enumerate() {
            if *r != usize::MAX {
                *r = global_of.len();
                global_of.push(g);
            }
        }
        Split { ranges, reduced_of, global_of }
    }

    /// The condensed body (position in `ranges`) whose elastic coordinates hold global index
    /// `g`, if any.
    fn block_of(&self, g: usize) -> Option<usize> {
        self.ranges.iter().position(|&(_, first, m)| g >= first && g < first + m)
    }
}

/// The coupling entries of every condensed body, by coupling unknown (global index), from the
/// global `pattern`, and the pattern of the reduced system: the entries of N_SS, the dense
/// J x J block of each body's coupling unknowns, and the diagonal.
fn couplings_and_reduced_pattern(
    pattern: &SparsePattern,
    split: &Split,
) -> (Vec<BTreeMap<usize, Coupling>>, SparsePattern) {
    let reduced_of = &split.reduced_of;
    let mut coupling_sets: Vec<BTreeMap<usize, Coupling>> = vec![Default::default(); split.ranges.len()];
    let mut builder = PatternBuilder::new(split.global_of.len());
    for c in 0..pattern.n {
        for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
            let r = pattern.row_idx[k];
            match (split.block_of(r), split.block_of(c)) {
                (None, None) => builder.add_entry(reduced_of[r], reduced_of[c]),
                (Some(b), None) => {
                    coupling_sets[b].entry(c).or_default().0.push((r - split.ranges[b].1, k));
                }
                (None, Some(b)) => {
                    coupling_sets[b].entry(r).or_default().1.push((c - split.ranges[b].1, k));
                }
                (Some(_), Some(_)) => {}
            }
        }
    }
    for set in &coupling_sets {
        let j: Vec<usize> = set.keys().map(|&g| reduced_of[g]).collect();
        builder.add_block(&j, &j);
    }
    builder.add_diagonal(&(0..split.global_of.len()).collect::<Vec<_>>());
    (coupling_sets, builder.build())
}

/// For each value of the reduced pattern, the global value index of `pattern` it copies
/// (usize::MAX for the fill of the J x J blocks).
fn copy_map(pattern: &SparsePattern, reduced_of: &[usize], reduced_pattern: &SparsePattern) -> Vec<usize> {
    let mut copy_from = vec![usize::MAX; reduced_pattern.nnz()];
    for c in 0..pattern.n {
        if reduced_of[c] == usize::MAX {
            continue;
        }
        for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
            let r = pattern.row_idx[k];
            if reduced_of[r] != usize::MAX {
                copy_from[reduced_pattern.index(reduced_of[r], reduced_of[c])] = k;
            }
        }
    }
    copy_from
}

impl Block {
    /// The block of the condensed body of `range` with its coupling entries `set`, in the
    /// reduced numbering `reduced_of` and pattern `reduced_pattern`; with `keep_image`, the
    /// buffers of its coupling images.
    fn new(
        model: &Model,
        range: ElasticRange,
        set: BTreeMap<usize, Coupling>,
        reduced_of: &[usize],
        reduced_pattern: &SparsePattern,
        keep_image: bool,
    ) -> Result<Self> {
        let (bi, first, m) = range;
        let coupling: Vec<usize> = set.keys().copied().collect();
        let reduced: Vec<usize> = coupling.iter().map(|&g| reduced_of[g]).collect();
        let schur_entries = reduced_pattern.block_indices(&reduced, &reduced);
        let (column_entries, row_entries): (Vec<_>, Vec<Vec<(usize, usize)>>) = set.into_values().unzip();
        let row_values = row_entries.iter().map(|e| vec![0.0; e.len()]).collect();
        let offset = model.bodies[bi].offset;
        let mut reference = [0usize; 7];
        for (r, slot) in reference.iter_mut().enumerate() {
            *slot =
                coupling.iter().position(|&g| g == offset + r).ok_or_else(|| FlexmbdError::InvalidModel {
                    item: format!("body '{}'", model.bodies[bi].name),
                    message: "condensed body without reference coupling".to_string(),
                })?;
        }
        Ok(Block {
            body: bi,
            first,
            n: m,
            z: vec![0.0; m * coupling.len()],
            w: if keep_image { vec![0.0; m * coupling.len()] } else { Vec::new() },
            image: if keep_image { vec![0.0; m] } else { Vec::new() },
            last_x: Vec::new(),
            dense_rows: row_entries
                .iter()
                .map(|e| e.len() == m && e.iter().enumerate().all(|(i, &(f, _))| f == i))
                .collect(),
            coupling,
            column_entries,
            row_entries,
            row_values,
            schur_entries,
            factors: Vec::new(),
            current: 0,
            reference,
            basis: Vec::new(),
            support: None,
            support_position: Vec::new(),
            basis_compact: Vec::new(),
            reference_rows: Vec::new(),
            structured: None,
            apply_kept: true,
            deformation: Vec::new(),
            antisymmetric_bound: None,
            angular_velocity: Vec3::ZERO,
            gyroscopic_coefficients: None,
            deformation_tolerance: super::reference::DEFORMATION_TOLERANCE,
        })
    }
}

impl CondensedSolver {
    /// Lays out the split of the model's Newton matrix (pattern `model.layout.pattern`). With
    /// `approximate_reference`, the coupling of each body with its reference coordinates is
    /// taken from its mass and velocity parts without solves (for iteration matrices, see
    /// `factorize`); else as assembled (exact).
    pub fn new(model: &Model, approximate_reference: bool) -> Result<Self> {
        Self::with_images(model, approximate_reference, false)
    }

    /// [`CondensedSolver::new`]; with `keep_image`, every solve also keeps W x_J of each block
    /// (see [`CondensedSolver::coupling_images`]).
    pub fn with_images(model: &Model, approximate_reference: bool, keep_image: bool) -> Result<Self> {
        let pattern = &model.layout.pattern;
        let split = Split::of(model);
        let (coupling_sets, reduced_pattern) = couplings_and_reduced_pattern(pattern, &split);
        let copy_from = copy_map(pattern, &split.reduced_of, &reduced_pattern);
        let lu = ReducedLu::new(reduced_pattern.clone()).map_err(|detail| FlexmbdError::SingularMatrix {
            time: 0.0,
            context: "symbolic analysis of the condensed Newton matrix".to_string(),
            detail,
        })?;
        let blocks = split
            .ranges
            .iter()
            .zip(coupling_sets)
            .map(|(&range, set)| {
                Block::new(model, range, set, &split.reduced_of, &reduced_pattern, keep_image)
            })
            .collect::<Result<Vec<_>>>()?;
        let y_len = blocks.iter().map(|b| b.n).sum();
        Ok(CondensedSolver {
            blocks,
            reduced_values: vec![0.0; reduced_pattern.nnz()],
            rhs: vec![0.0; split.global_of.len()],
            y: vec![0.0; y_len],
            reduced_of: split.reduced_of,
            global_of: split.global_of,
            copy_from,
            lu,
            approximate_reference,
            factorized: false,
            keep_image,
            gyroscopic: false,
            gyroscopic_scale: 0.0,
            reduced_pattern: reduced_pattern.clone(),
            coarse: None,
        })
    }
}
