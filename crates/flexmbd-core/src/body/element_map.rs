//! How an element of a deformable body reads its local coordinates from the body's elastic
//! coordinates, and how its force and tangent go back: e = map q_l over the n_l coordinates
//! `indices` (map: n_e x n_l, row-major; a rotation to element axes times the selection of
//! its nodes' coordinates, or times the mode shapes of a modal body), f_l = map^T f and
//! w map^T k map added at `positions` of the body's elastic pattern. A nodal beam's map has
//! at most three entries per row: those rows are kept sparse.

/// An element placed on a body's elastic coordinates.
pub trait MappedElement {
    /// The body's elastic coordinates the element depends on (n_l).
    fn indices(&self) -> &[usize];
    /// e = map q_l: n_e x n_l, row-major.
    fn map(&self) -> &[f64];
    /// Positions of the (indices[i], indices[j]) pairs in the body's elastic pattern.
    fn positions(&self) -> &[usize];
    /// The map's rows by their entries, when they are few.
    fn sparse_map(&self) -> Option<&SparseMap>;
}

/// Implements [`MappedElement`] for an element type with the fields `indices`, `map`,
/// `positions` and `sparse_map`.
#[macro_export]
macro_rules! mapped_element {
    ($element:ty) => {
        impl $crate::body::element_map::MappedElement for $element {
            fn indices(&self) -> &[usize] {
                &self.indices
            }
            fn map(&self) -> &[f64] {
                &self.map
            }
            fn positions(&self) -> &[usize] {
                &self.positions
            }
            fn sparse_map(&self) -> Option<&$crate::body::element_map::SparseMap> {
                self.sparse_map.as_ref()
            }
        }
    };
}

/// The rows of a map e = map q_l by their nonzero entries (row r: `entries[start[r]..start[r
/// + 1]]` of (column, value)).
#[derive(Clone, Debug, PartialEq)]
pub struct SparseMap {
    start: Vec<usize>,
    entries: Vec<(usize, f64)>,
}

/// A map row with more nonzero entries than this on average is used dense.
const SPARSE_MAP_ROW: usize = 3;

impl SparseMap {
    /// The sparse rows of `map` (n_e x n_l, row-major) when they hold at most
    /// `SPARSE_MAP_ROW` nonzero entries on average and fewer than the dense rows.
    pub fn of(map: &[f64], ne: usize, nl: usize) -> Option<SparseMap> {
        let nonzero = map.iter().filter(|v| **v != 0.0).count();
        if ne == 0 || nonzero > SPARSE_MAP_ROW * ne || nonzero >= ne * nl {
            return None;
        }
        let mut start = Vec::with_capacity(ne + 1);
        let mut entries = Vec::with_capacity(nonzero);
        start.push(0);
        for r in 0..ne {
            let row = map[r * nl..(r + 1) * nl].iter().enumerate();
            entries.extend(row.filter(|(_, v)| **v != 0.0).map(|(j, v)| (j, *v)));
            start.push(entries.len());
        }
        Some(SparseMap { start, entries })
    }

    fn row(&self, r: usize) -> &[(usize, f64)] {
        &self.entries[self.start[r]..self.start[r + 1]]
    }
}

/// e = map q_l (e: n_e).
pub fn gather<E: MappedElement>(el: &E, qf: &[f64], e: &mut [f64]) {
    let (indices, map) = (el.indices(), el.map());
    let n = indices.len();
    match el.sparse_map() {
        Some(sm) => {
            for (r, er) in e.iter_mut().enumerate() {
                *er = sm.row(r).iter().map(|&(j, v)| v * qf[indices[j]]).sum();
            }
        }
        None => {
            for (r, er) in e.iter_mut().enumerate() {
                *er = (0..n).map(|j| map[r * n + j] * qf[indices[j]]).sum();
            }
        }
    }
}

/// out[indices] += map^T f.
pub fn scatter<E: MappedElement>(el: &E, f: &[f64], out: &mut [f64]) {
    let (indices, map) = (el.indices(), el.map());
    let n = indices.len();
    match el.sparse_map() {
        Some(sm) => {
            for (r, fr) in f.iter().enumerate() {
                for &(j, v) in sm.row(r) {
                    out[indices[j]] += v * fr;
                }
            }
        }
        None => {
            for j in 0..n {
                out[indices[j]] += f.iter().enumerate().map(|(r, fr)| map[r * n + j] * fr).sum::<f64>();
            }
        }
    }
}

/// values[positions] += w map^T k map (k: n_e x n_e, row-major); `kb` is scratch.
pub fn add_tangent<E: MappedElement>(el: &E, w: f64, k: &[f64], values: &mut [f64], kb: &mut Vec<f64>) {
    let (map, positions) = (el.map(), el.positions());
    let n = el.indices().len();
    let ne = (k.len() as f64).sqrt().round() as usize;
    if let Some(sm) = el.sparse_map() {
        for r in 0..ne {
            for s in 0..ne {
                let krs = w * k[r * ne + s];
                if krs == 0.0 {
                    continue;
                }
                for &(i, vi) in sm.row(r) {
                    for &(j, vj) in sm.row(s) {
                        values[positions[i * n + j]] += vi * krs * vj;
                    }
                }
            }
        }
        return;
    }
    // k B with B = map (n_e x n_l), then B^T (k B).
    kb.clear();
    kb.resize(ne * n, 0.0);
    for r in 0..ne {
        for j in 0..n {
            kb[r * n + j] = (0..ne).map(|s| k[r * ne + s] * map[s * n + j]).sum();
        }
    }
    for i in 0..n {
        for j in 0..n {
            let v: f64 = (0..ne).map(|r| map[r * n + i] * kb[r * n + j]).sum();
            values[positions[i * n + j]] += w * v;
        }
    }
}

/// Adds the nonlinear forces of all `elements` to `out` (n_f) and, with
/// `tangent = Some((w, values))`, w times their tangents to the values of the elastic
/// pattern; returns the sum of their energies. `local_count(el)` is the element's n_e and
/// `terms(el, e, f, k)` its energy, force f (n_e) and, if asked, tangent k (n_e x n_e) at e.
pub fn add_elements<E: MappedElement>(
    elements: &[E],
    qf: &[f64],
    out: &mut [f64],
    mut tangent: Option<(f64, &mut [f64])>,
    local_count: impl Fn(&E) -> usize,
    mut terms: impl FnMut(&E, &[f64], &mut [f64], Option<&mut [f64]>) -> f64,
) -> f64 {
    let mut energy = 0.0;
    let (mut e, mut f, mut k, mut kb) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for el in elements {
        let ne = local_count(el);
        e.clear();
        e.resize(ne, 0.0);
        gather(el, qf, &mut e);
        f.clear();
        f.resize(ne, 0.0);
        let want = tangent.is_some();
        if want {
            k.clear();
            k.resize(ne * ne, 0.0);
        }
        energy += terms(el, &e, &mut f, if want { Some(&mut k) } else { None });
        scatter(el, &f, out);
        if let Some((w, values)) = tangent.as_mut() {
            add_tangent(el, *w, &k, values, &mut kb);
        }
    }
    energy
}
