//! Envelope (profile, skyline) Cholesky factorization of small sparse positive definite
//! matrices in reverse Cuthill-McKee order (George and Liu, Computer Solution of Large Sparse
//! Positive Definite Systems, 1981, chapter 4).
//!
//! Row i of the factor L is stored densely from its first nonzero column f_i to the diagonal.
//! Both triangular solves then run over contiguous rows (a dot product per row forward, an
//! update of a contiguous span per row backward), without the index lists and the per-block
//! dispatch of a supernodal solve. For the matrices of small meshes (a thousand unknowns) the
//! envelope of the reverse Cuthill-McKee order holds fewer entries than the supernodal factor
//! of a nested dissection, and the solve is up to three times faster (`benchmarks/README.md`);
//! for large meshes the envelope grows much faster than the fill, and
//! [`crate::linalg::symmetric::SymmetricFactor`] keeps its supernodal factor (see `ENVELOPE_LIMIT` there).

use crate::linalg::simd::{group_dot, group_update, has_avx2_fma, mul_add, GROUP};

/// Reverse Cuthill-McKee ordering (position -> unknown) of the graph of a symmetric matrix
/// given by its lower triangle in CSC form (`ptr`, `idx`; diagonal entries may be present).
/// Each connected component starts from a pseudo-peripheral node (George and Liu's search),
/// the neighbours of a node are numbered in increasing degree, and the order is reversed.
pub fn reverse_cuthill_mckee(n: usize, ptr: &[usize], idx: &[usize]) -> Vec<usize> {
    let mut degree = vec![0usize; n];
    for c in 0..n {
        for &r in &idx[ptr[c]..ptr[c + 1]] {
            if r != c {
                degree[r] += 1;
                degree[c] += 1;
            }
        }
    }
    let mut adj_ptr = vec![0usize; n + 1];
    for i in 0..n {
        adj_ptr[i + 1] = adj_ptr[i] + degree[i];
    }
    let mut fill = adj_ptr[..n].to_vec();
    let mut adj = vec![0usize; adj_ptr[n]];
    for c in 0..n {
        for &r in &idx[ptr[c]..ptr[c + 1]] {
            if r != c {
                adj[fill[r]] = c;
                fill[r] += 1;
                adj[fill[c]] = r;
                fill[c] += 1;
            }
        }
    }
    for i in 0..n {
        adj[adj_ptr[i]..adj_ptr[i + 1]].sort_unstable_by_key(|&j| (degree[j], j));
    }
    let neighbours = |i: usize| &adj[adj_ptr[i]..adj_ptr[i + 1]];

    let mut order = Vec::with_capacity(n);
    let mut numbered = vec![false; n];
    // Scratch of the level searches: the level of each node (usize::MAX unreached).
    let mut level = vec![usize::MAX; n];
    let mut queue = Vec::with_capacity(n);
    // Breadth-first levels from `root` within its component; returns (eccentricity, the
    // nodes of the last level) and leaves the reached nodes in `queue`.
    let levels = |root: usize, level: &mut Vec<usize>, queue: &mut Vec<usize>| -> (usize, Vec<usize>) {
        for &i in queue.iter() {
            level[i] = usize::MAX;
        }
        queue.clear();
        queue.push(root);
        level[root] = 0;
        let mut head = 0;
        while head < queue.len() {
            let i = queue[head];
            head += 1;
            for &j in neighbours(i) {
                if level[j] == usize::MAX {
                    level[j] = level[i] + 1;
                    queue.push(j);
                }
            }
        }
        let depth = level[*queue.last().expect("the root is queued")];
        let last = queue.iter().copied().filter(|&i| level[i] == depth).collect();
        (depth, last)
    };
    for start in 0..n {
        if numbered[start] {
            continue;
        }
        // Pseudo-peripheral root: from the node of least degree in the component, move to a
        // node of least degree in the last level while the eccentricity grows.
        let (_, _) = levels(start, &mut level, &mut queue);
        let mut root = queue.iter().copied().min_by_key(|&i| (degree[i], i)).expect("nonempty");
        let (mut depth, mut last) = levels(root, &mut level, &mut queue);
        loop {
            let candidate = last.iter().copied().min_by_key(|&i| (degree[i], i)).expect("nonempty");
            let (d, l) = levels(candidate, &mut level, &mut queue);
            if d > depth {
                root = candidate;
                depth = d;
                last = l;
            } else {
                break;
            }
        }
        // Cuthill-McKee numbering of the component from the root.
        let first = order.len();
        order.push(root);
        numbered[root] = true;
        let mut head = first;
        while head < order.len() {
            let i = order[head];
            head += 1;
            for &j in neighbours(i) {
                if !numbered[j] {
                    numbered[j] = true;
                    order.push(j);
                }
            }
        }
        for &i in queue.iter() {
            level[i] = usize::MAX;
        }
        queue.clear();
    }
    order.reverse();
    order
}

/// The inverse of a permutation (unknown -> position for an order position -> unknown).
fn inverse(order: &[usize]) -> Vec<usize> {
    let mut position = vec![0usize; order.len()];
    for (p, &u) in order.iter().enumerate() {
        position[u] = p;
    }
    position
}

/// Dot product in sixteen independent partial sums (four vectors of four with AVX2; a single
/// running sum would be a chain of dependent additions).
#[inline(always)]
fn dot<const FMA: bool>(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut s = [0.0f64; 16];
    let mut ca = a.chunks_exact(16);
    let mut cb = b.chunks_exact(16);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for k in 0..16 {
            s[k] = mul_add::<FMA>(x[k], y[k], s[k]);
        }
    }
    let (ra, rb) = (ca.remainder(), cb.remainder());
    let mut ca = ra.chunks_exact(4);
    let mut cb = rb.chunks_exact(4);
    let mut t = [0.0f64; 4];
    for (x, y) in (&mut ca).zip(&mut cb) {
        for k in 0..4 {
            t[k] = mul_add::<FMA>(x[k], y[k], t[k]);
        }
    }
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        t[0] = mul_add::<FMA>(*x, *y, t[0]);
    }
    for k in 0..4 {
        t[k] += (s[k] + s[k + 8]) + (s[k + 4] + s[k + 12]);
    }
    (t[0] + t[2]) + (t[1] + t[3])
}

/// The envelope Cholesky factor L L^T = P A P^T of a symmetric positive definite matrix.
#[derive(Debug, Clone)]
pub struct EnvelopeCholesky {
    n: usize,
    /// Position -> unknown.
    order: Vec<usize>,
    /// First stored column of each row (in the permuted numbering).
    first: Vec<usize>,
    /// Offset of each row's entries in `values`; row i holds columns first[i]..=i.
    start: Vec<usize>,
    values: Vec<f64>,
    /// 1 / L_ii: the solves multiply (a division in the chain of dependent rows costs about
    /// as much as the row's dot product).
    inverse_diagonal: Vec<f64>,
}

/// A pivot that is not positive: the matrix is not positive definite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NotPositive {
    /// The unknown whose pivot failed.
    pub unknown: usize,
    /// Its pivot before the square root.
    pub pivot: f64,
}

impl EnvelopeCholesky {
    /// First column of each row of the envelope of the lower triangle (`ptr`, `idx`, CSC) in
    /// `order`.
    fn first_columns(n: usize, ptr: &[usize], idx: &[usize], order: &[usize]) -> Vec<usize> {
        let position = inverse(order);
        let mut first: Vec<usize> = (0..n).collect();
        for c in 0..n {
            for &r in &idx[ptr[c]..ptr[c + 1]] {
                let (pr, pc) = (position[r], position[c]);
                let (row, col) = if pr >= pc { (pr, pc) } else { (pc, pr) };
                first[row] = first[row].min(col);
            }
        }
        first
    }

    /// Pads the rows so that the solves run over whole vectors of four entries: the rows of
    /// each group i..i + GROUP (i a multiple of GROUP) start at one column m with i - m a
    /// multiple of four (where the rows are long enough), as does each row after the last
    /// whole group. The padded entries are zero in A and stay zero in L: a row of L is zero
    /// before the first nonzero of the row of A (George and Liu, theorem 4.1.1).
    fn align_groups(first: &mut [usize]) {
        let aligned = |i: usize, f: usize| {
            let span = (i - f).div_ceil(4) * 4;
            if span <= i {
                i - span
            } else {
                f
            }
        };
        let n = first.len();
        let whole = n - n % GROUP;
        for group in first[..whole].chunks_exact_mut(GROUP).enumerate().map(|(g, rows)| (g * GROUP, rows)) {
            let (i, rows) = group;
            let m = aligned(i, *rows.iter().min().expect("a group has rows"));
            rows.fill(m);
        }
        for (i, f) in first.iter_mut().enumerate().skip(whole) {
            *f = aligned(i, *f);
        }
    }

    /// The structure of the envelope of the lower triangle (`ptr`, `idx`, CSC, diagonal
    /// included or not) in `order` (position -> unknown, a permutation), rows padded as
    /// [`Self::align_groups`] says. Its values are allocated and set by [`Self::factorize`],
    /// so that [`Self::len`] can be checked first.
    pub fn new(n: usize, ptr: &[usize], idx: &[usize], order: Vec<usize>) -> Self {
        let mut first = Self::first_columns(n, ptr, idx, &order);
        Self::align_groups(&mut first);
        let mut start = Vec::with_capacity(n + 1);
        start.push(0);
        for i in 0..n {
            start.push(start[i] + i + 1 - first[i]);
        }
        EnvelopeCholesky { n, order, first, start, values: Vec::new(), inverse_diagonal: vec![0.0; n] }
    }

    /// Order of the matrix.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Entries of L in the envelope.
    pub fn len(&self) -> usize {
        self.start[self.n]
    }

    /// True for the empty matrix.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Factorizes the matrix whose lower triangle (`ptr`, `idx`, `values`, CSC, the pattern
    /// given to [`Self::new`] or a part of it; duplicates summed) is given.
    pub fn factorize(&mut self, ptr: &[usize], idx: &[usize], values: &[f64]) -> Result<(), NotPositive> {
        self.load(ptr, idx, values);
        if has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked above).
            #[cfg(target_arch = "x86_64")]
            return unsafe { self.factor_rows_avx2() };
        }
        self.factor_rows::<false>()
    }

    /// The matrix entries into the envelope (permuted, lower triangle).
    fn load(&mut self, ptr: &[usize], idx: &[usize], values: &[f64]) {
        let n = self.n;
        let position = inverse(&self.order);
        self.values.clear();
        self.values.resize(self.len(), 0.0);
        for c in 0..n {
            for k in ptr[c]..ptr[c + 1] {
                let (pr, pc) = (position[idx[k]], position[c]);
                let (row, col) = if pr >= pc { (pr, pc) } else { (pc, pr) };
                self.values[self.start[row] + col - self.first[row]] += values[k];
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn factor_rows_avx2(&mut self) -> Result<(), NotPositive> {
        self.factor_rows::<true>()
    }

    /// Row by row: L_ij = (A_ij - L_i. L_j.) / L_jj over the common span, then the pivot.
    #[inline(always)]
    fn factor_rows<const FMA: bool>(&mut self) -> Result<(), NotPositive> {
        let n = self.n;
        let (first, start) = (&self.first, &self.start);
        for i in 0..n {
            let fi = first[i];
            let (done, rest) = self.values.split_at_mut(start[i]);
            let row = &mut rest[..i + 1 - fi];
            for j in fi..i {
                let fj = first[j];
                let from = fi.max(fj);
                let row_j = &done[start[j]..start[j + 1]];
                let s = dot::<FMA>(&row[from - fi..j - fi], &row_j[from - fj..j - fj]);
                row[j - fi] = (row[j - fi] - s) * self.inverse_diagonal[j];
            }
            let d = row[i - fi] - dot::<FMA>(&row[..i - fi], &row[..i - fi]);
            if !(d > 0.0) {
                return Err(NotPositive { unknown: self.order[i], pivot: d });
            }
            row[i - fi] = d.sqrt();
            self.inverse_diagonal[i] = 1.0 / row[i - fi];
        }
        Ok(())
    }

    /// Solves A x = b in place; `scratch` has at least n entries.
    pub fn solve(&self, x: &mut [f64], scratch: &mut [f64]) {
        if has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked above).
            #[cfg(target_arch = "x86_64")]
            return unsafe { self.solve_avx2(x, scratch) };
        }
        self.solve_rows::<false>(x, scratch);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn solve_avx2(&self, x: &mut [f64], scratch: &mut [f64]) {
        self.solve_rows::<true>(x, scratch);
    }

    /// The two triangular solves over the rows: a dot product per row forward (L y = P b), an
    /// update of the row's span backward (L^T z = y, by rows of L). Rows are taken in groups
    /// of GROUP that start at one column (`align_groups`): one pass over y serves the group
    /// (a load of y per GROUP entries of L forward, and per GROUP entries a load and a store
    /// backward), in whole vectors of four; the triangle of the group's own columns apart.
    #[inline(always)]
    fn solve_rows<const FMA: bool>(&self, x: &mut [f64], scratch: &mut [f64]) {
        let n = self.n;
        let whole = n - n % GROUP;
        let y = &mut scratch[..n];
        for (yi, &u) in y.iter_mut().zip(&self.order) {
            *yi = x[u];
        }
        let row = |i: usize| &self.values[self.start[i]..self.start[i + 1]];
        let inv = &self.inverse_diagonal;
        for i in (0..whole).step_by(GROUP) {
            let m = self.first[i];
            let rows: [&[f64]; GROUP] = std::array::from_fn(|r| row(i + r));
            let sums = group_dot::<FMA>(rows, &y[m..i]);
            // The group's own triangle with its values in registers (through y in memory,
            // each row waited for the store and load of the one before).
            let mut v: [f64; GROUP] = std::array::from_fn(|r| y[i + r]);
            for (r, (l, mut s)) in rows.iter().zip(sums).enumerate() {
                for (c, &lc) in l[i - m..i - m + r].iter().enumerate() {
                    s = mul_add::<FMA>(lc, v[c], s);
                }
                v[r] = (v[r] - s) * inv[i + r];
            }
            y[i..i + GROUP].copy_from_slice(&v);
        }
        for i in whole..n {
            let fi = self.first[i];
            let s = dot::<FMA>(&row(i)[..i - fi], &y[fi..i]);
            y[i] = (y[i] - s) * inv[i];
        }
        for i in (whole..n).rev() {
            let fi = self.first[i];
            let xi = y[i] * inv[i];
            y[i] = xi;
            for (yj, l) in y[fi..i].iter_mut().zip(row(i)) {
                *yj = mul_add::<FMA>(-xi, *l, *yj);
            }
        }
        for i in (0..whole).step_by(GROUP).rev() {
            let m = self.first[i];
            let rows: [&[f64]; GROUP] = std::array::from_fn(|r| row(i + r));
            let mut v: [f64; GROUP] = std::array::from_fn(|r| y[i + r]);
            for r in (0..GROUP).rev() {
                let xr = v[r] * inv[i + r];
                v[r] = xr;
                for (c, &lc) in rows[r][i - m..i - m + r].iter().enumerate() {
                    v[c] = mul_add::<FMA>(-xr, lc, v[c]);
                }
            }
            y[i..i + GROUP].copy_from_slice(&v);
            group_update::<FMA>(&mut y[m..i], v, rows);
        }
        for (yi, &u) in y.iter().zip(&self.order) {
            x[u] = *yi;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::assert_all_close;

    /// Lower triangle (CSC) of the 5-point Laplacian of an m x m grid plus shift I, numbered
    /// row by row, then relabelled by `shuffle` (so that the natural order is a bad one).
    fn grid(m: usize, shift: f64, shuffle: bool) -> (usize, Vec<usize>, Vec<usize>, Vec<f64>) {
        let n = m * m;
        let label = |k: usize| if shuffle { (k * 89) % n } else { k };
        let mut columns: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        for i in 0..m {
            for j in 0..m {
                let k = i * m + j;
                let mut add = |a: usize, b: usize, v: f64| {
                    let (a, b) = (label(a), label(b));
                    let (r, c) = if a >= b { (a, b) } else { (b, a) };
                    columns[c].push((r, v));
                };
                add(k, k, 4.0 + shift);
                if j + 1 < m {
                    add(k, k + 1, -1.0);
                }
                if i + 1 < m {
                    add(k, k + m, -1.0);
                }
            }
        }
        let mut ptr = vec![0];
        let (mut idx, mut val) = (Vec::new(), Vec::new());
        for mut col in columns {
            col.sort_by_key(|e| e.0);
            for (r, v) in col {
                idx.push(r);
                val.push(v);
            }
            ptr.push(idx.len());
        }
        (n, ptr, idx, val)
    }

    fn multiply(n: usize, ptr: &[usize], idx: &[usize], val: &[f64], x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; n];
        for c in 0..n {
            for k in ptr[c]..ptr[c + 1] {
                let r = idx[k];
                y[r] += val[k] * x[c];
                if r != c {
                    y[c] += val[k] * x[r];
                }
            }
        }
        y
    }

    #[test]
    fn solves_a_shuffled_grid_laplacian_to_round_off() {
        // Orders with and without rows after the last whole group of the solves.
        solve_grid(12);
        solve_grid(7);
        solve_grid(5);
    }

    fn solve_grid(m: usize) {
        let (n, ptr, idx, val) = grid(m, 0.1, true);
        let order = reverse_cuthill_mckee(n, &ptr, &idx);
        let mut f = EnvelopeCholesky::new(n, &ptr, &idx, order);
        f.factorize(&ptr, &idx, &val).expect("positive definite");
        let b: Vec<f64> = (0..n).map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.3).collect();
        let mut x = b.clone();
        f.solve(&mut x, &mut vec![0.0; n]);
        let r = multiply(n, &ptr, &idx, &val, &x);
        let err = r.iter().zip(&b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(err < 1e-12, "residual {err}");
        // The portable kernels (the solve above takes the AVX2 ones where the CPU has them)
        // agree to round-off, factor and solve.
        let mut portable = f.clone();
        portable.load(&ptr, &idx, &val);
        portable.factor_rows::<false>().expect("positive definite");
        assert_all_close(&f.values, &portable.values, 0.0, 1e-14, "portable factor");
        let mut y = b.clone();
        portable.solve_rows::<false>(&mut y, &mut vec![0.0; n]);
        assert_all_close(&y, &x, 0.0, 1e-13, "portable solution");
    }

    #[test]
    fn solves_chains_of_every_length_of_the_last_group() {
        // Tridiagonal (chain) matrices of orders 1 to 11 with a coupling to the first unknown:
        // every count of rows after the last whole group of the solves, groups shorter than
        // a vector, in the portable and the AVX2 kernels.
        for n in 1..=11usize {
            let (mut ptr, mut idx, mut val) = (vec![0], Vec::new(), Vec::new());
            for c in 0..n {
                idx.push(c);
                val.push(4.0 + c as f64);
                if c + 1 < n {
                    idx.push(c + 1);
                    val.push(-1.0);
                }
                if c == 0 && n > 3 {
                    idx.push(n - 1);
                    val.push(0.5);
                }
                ptr.push(idx.len());
            }
            let order = reverse_cuthill_mckee(n, &ptr, &idx);
            let mut f = EnvelopeCholesky::new(n, &ptr, &idx, order);
            f.factorize(&ptr, &idx, &val).expect("positive definite");
            let b: Vec<f64> = (0..n).map(|i| 1.0 - 0.3 * i as f64).collect();
            for fma in [false, true] {
                let mut x = b.clone();
                if fma {
                    f.solve(&mut x, &mut vec![0.0; n]);
                } else {
                    f.solve_rows::<false>(&mut x, &mut vec![0.0; n]);
                }
                let r = multiply(n, &ptr, &idx, &val, &x);
                let err = r.iter().zip(&b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
                assert!(err < 1e-13, "order {n}: residual {err}");
            }
        }
    }

    #[test]
    fn reverse_cuthill_mckee_gives_the_band_of_a_grid() {
        // A grid of m x m nodes has a bandwidth of m in its row-by-row numbering; the
        // shuffled labels have a band of the order of n. The RCM order finds a band of about
        // m again (its envelope at most m+1 entries per row), and is a permutation.
        let m = 12;
        let (n, ptr, idx, _) = grid(m, 0.0, true);
        // The profile without the padding of the solves.
        let profile = |order: &[usize]| -> usize {
            let first = EnvelopeCholesky::first_columns(n, &ptr, &idx, order);
            first.iter().enumerate().map(|(i, f)| i + 1 - f).sum()
        };
        let shuffled = profile(&(0..n).collect::<Vec<_>>());
        let order = reverse_cuthill_mckee(n, &ptr, &idx);
        let mut seen = vec![false; n];
        for &u in &order {
            assert!(!seen[u]);
            seen[u] = true;
        }
        assert_eq!(order.len(), n);
        let rcm = profile(&order);
        assert!(rcm <= n * (m + 1), "RCM envelope {rcm}");
        assert!(shuffled > 4 * rcm, "shuffled envelope {shuffled} against {rcm}");
    }

    #[test]
    fn rows_are_padded_in_groups_to_whole_vectors() {
        // The rows of each group i..i + GROUP start at one column m <= the first nonzero of
        // each, with i - m a multiple of four wherever the rows are long enough (and m = the
        // first nonzero before): at most three entries of padding below the group's first
        // nonzero; the rows after the last whole group alike, each alone.
        for m in [7, 12] {
            let (n, ptr, idx, _) = grid(m, 0.0, true);
            let order = reverse_cuthill_mckee(n, &ptr, &idx);
            let exact = EnvelopeCholesky::first_columns(n, &ptr, &idx, &order);
            let f = EnvelopeCholesky::new(n, &ptr, &idx, order);
            let whole = n - n % GROUP;
            let groups = (0..whole).step_by(GROUP).map(|i| (i, GROUP)).chain((whole..n).map(|i| (i, 1)));
            for (i, size) in groups {
                let low = *exact[i..i + size].iter().min().expect("rows");
                let padded = f.first[i];
                assert!(f.first[i..i + size].iter().all(|&c| c == padded), "rows {i}..");
                assert!(padded <= low, "row {i}: {padded} > {low}");
                if (i - low).div_ceil(4) * 4 <= i {
                    assert_eq!((i - padded) % 4, 0, "row {i}");
                    assert!(low - padded <= 3, "row {i}");
                } else {
                    assert_eq!(padded, low);
                }
            }
        }
    }

    #[test]
    fn components_are_ordered_each_and_an_indefinite_matrix_names_its_pivot() {
        // Two disconnected grids: every unknown is ordered once.
        let (n1, ptr1, idx1, val1) = grid(4, 0.0, false);
        let (mut ptr, mut idx, mut val) = (ptr1.clone(), idx1.clone(), val1.clone());
        for c in 0..n1 {
            for k in ptr1[c]..ptr1[c + 1] {
                idx.push(idx1[k] + n1);
                val.push(val1[k]);
            }
            ptr.push(idx.len());
        }
        let n = 2 * n1;
        let order = reverse_cuthill_mckee(n, &ptr, &idx);
        assert_eq!(order.len(), n);
        let mut f = EnvelopeCholesky::new(n, &ptr, &idx, order.clone());
        f.factorize(&ptr, &idx, &val).expect("positive definite");
        let b = vec![1.0; n];
        let mut x = b.clone();
        f.solve(&mut x, &mut vec![0.0; n]);
        let r = multiply(n, &ptr, &idx, &val, &x);
        assert_all_close(&r, &b, 0.0, 1e-12, "A x against b = 1");
        // Shift the second grid's diagonal down by 8.1: its smallest eigenvalue becomes
        // negative and a pivot fails, named by an unknown of that grid.
        for c in n1..n {
            let k = (ptr[c]..ptr[c + 1]).find(|&k| idx[k] == c).expect("diagonal");
            val[k] -= 8.1;
        }
        let mut f = EnvelopeCholesky::new(n, &ptr, &idx, order);
        let err = f.factorize(&ptr, &idx, &val).expect_err("indefinite");
        assert!(err.unknown >= n1 && err.pivot <= 0.0, "{err:?}");
    }
}
