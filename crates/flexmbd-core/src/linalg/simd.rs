//! Small kernels for the hot loops of a step: the dot products of a group of rows with one
//! vector and the update of a vector by a combination of rows (the envelope solves, the
//! condensed solve's coupling), products with 3 x 3 node blocks (K_ff q_f), the node-wise
//! products of a scalar mass matrix and products with dense column-major matrices. AVX2 and
//! FMA intrinsics where the CPU has them (checked at run time), portable code otherwise
//! (tested to agree to round-off).

/// Multiply-add: fused (one rounding) in the kernels compiled for FMA, else a product and a
/// sum (`f64::mul_add` without the instruction would be a library call).
#[inline(always)]
pub(crate) fn mul_add<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Whether the kernels compiled for AVX2 and FMA can run here (checked once by the standard
/// library's cached CPU detection).
#[inline]
pub(crate) fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Rows taken together by the group kernels (the envelope solves' groups, see
/// `EnvelopeCholesky::align_groups`).
pub(crate) const GROUP: usize = 4;

/// The dot products of a group's rows with y: the AVX2 kernel in the FMA build (the
/// compiler's own vectorization of [`dot_rows`] mixes half-width vectors and shuffles).
#[inline(always)]
pub(crate) fn group_dot<const FMA: bool>(rows: [&[f64]; GROUP], y: &[f64]) -> [f64; GROUP] {
    #[cfg(target_arch = "x86_64")]
    if FMA {
        // SAFETY: the FMA kernels run only from callers that checked AVX2 and FMA
        // (`has_avx2_fma`).
        return unsafe { avx2::dot4(rows, y) };
    }
    dot_rows::<FMA, GROUP>(rows, y)
}

/// y -= sum_r x_r rows_r for a group: the AVX2 kernel in the FMA build.
#[inline(always)]
pub(crate) fn group_update<const FMA: bool>(y: &mut [f64], x: [f64; GROUP], rows: [&[f64]; GROUP]) {
    #[cfg(target_arch = "x86_64")]
    if FMA {
        // SAFETY: as in `group_dot`.
        return unsafe { avx2::update4(y, x, rows) };
    }
    update_rows::<FMA, GROUP>(y, x, rows)
}

/// The kernels in AVX2 and FMA intrinsics.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use std::arch::x86_64::{
        __m256d, _mm256_add_pd, _mm256_fmadd_pd, _mm256_hadd_pd, _mm256_loadu_pd, _mm256_maskload_pd,
        _mm256_maskstore_pd, _mm256_mul_pd, _mm256_permute2f128_pd, _mm256_permute4x64_pd, _mm256_set1_pd,
        _mm256_setr_epi64x, _mm256_setzero_pd, _mm256_storeu_pd,
    };

    /// out[4 i + k] = sum over the entries (r, m) of column i of a CSC matrix of
    /// m x[4 r + k], k < 4: one vector of four per entry.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(crate) unsafe fn node_products4(
        col_ptr: &[usize],
        row_idx: &[usize],
        values: &[f64],
        x: &[f64],
        out: &mut [f64],
    ) {
        for (col, node_out) in out.chunks_exact_mut(4).enumerate().take(col_ptr.len() - 1) {
            let range = col_ptr[col]..col_ptr[col + 1];
            let mut a = _mm256_setzero_pd();
            for (&row, &m) in row_idx[range.clone()].iter().zip(&values[range]) {
                let source = &x[4 * row..4 * row + 4];
                a = _mm256_fmadd_pd(_mm256_set1_pd(m), _mm256_loadu_pd(source.as_ptr()), a);
            }
            _mm256_storeu_pd(node_out.as_mut_ptr(), a);
        }
    }

    /// out[9 i + k] = sum over the entries (r, m) of column i of a CSC matrix of
    /// m gathered[9 r + k], k < W (6 or 9): per entry one or two vectors of four and, for
    /// W = 9, the ninth entry apart. Returns the sums over the columns i of
    /// gathered[9 i + j] out[9 i + l], j < 9, l < 3 (lane l of entry j; lane 3 is not used).
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(crate) unsafe fn node_products<const W: usize>(
        col_ptr: &[usize],
        row_idx: &[usize],
        values: &[f64],
        gathered: &[f64],
        out: &mut [f64],
    ) -> [[f64; 4]; 9] {
        use std::arch::x86_64::{_mm_fmadd_pd, _mm_loadu_pd, _mm_set1_pd, _mm_setzero_pd, _mm_storeu_pd};
        let mut moments = [_mm256_setzero_pd(); 9];
        for (col, node_out) in out.chunks_exact_mut(9).enumerate().take(col_ptr.len() - 1) {
            let range = col_ptr[col]..col_ptr[col + 1];
            let (mut a, mut b, mut b2) = (_mm256_setzero_pd(), _mm256_setzero_pd(), _mm_setzero_pd());
            let mut c = 0.0f64;
            for (&row, &m) in row_idx[range.clone()].iter().zip(&values[range]) {
                let source = &gathered[9 * row..9 * row + 9];
                let p = source.as_ptr();
                a = _mm256_fmadd_pd(_mm256_set1_pd(m), _mm256_loadu_pd(p), a);
                if W == 9 {
                    b = _mm256_fmadd_pd(_mm256_set1_pd(m), _mm256_loadu_pd(p.add(4)), b);
                    c = m.mul_add(source[8], c);
                } else {
                    b2 = _mm_fmadd_pd(_mm_set1_pd(m), _mm_loadu_pd(p.add(4)), b2);
                }
            }
            let o = node_out.as_mut_ptr();
            _mm256_storeu_pd(o, a);
            if W == 9 {
                _mm256_storeu_pd(o.add(4), b);
                node_out[8] = c;
            } else {
                _mm_storeu_pd(o.add(4), b2);
            }
            let own = &gathered[9 * col..9 * col + 9];
            for (sum, &v) in moments.iter_mut().zip(own) {
                *sum = _mm256_fmadd_pd(_mm256_set1_pd(v), a, *sum);
            }
        }
        let mut sums = [[0.0f64; 4]; 9];
        for (s, m) in sums.iter_mut().zip(&moments) {
            _mm256_storeu_pd(s.as_mut_ptr(), *m);
        }
        sums
    }

    /// out[3 i + k] += w (sum over the blocks B of block row i of B x_(block column)), for
    /// 3 x 3 blocks stored row-major: per block, [b0 b1 b2 b3] . [x0 x1 x2 x0] and
    /// [b4 b5 b6 b7] . [x1 x2 x0 x1] in two vectors and b8 x2 apart, the three sums sorted
    /// out at the end of the row (x is read through a mask, so that the last node needs no
    /// fourth entry). With `SYMMETRIC`, the blocks are the upper half (block column >= block
    /// row) of a symmetric matrix, and each off-diagonal block B of row i also adds w B^T x_i
    /// to the rows of its column (three lanes, read and written through the mask).
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(crate) unsafe fn blocks3_mul_add<const SYMMETRIC: bool>(
        row_ptr: &[usize],
        columns: &[u32],
        values: &[[f64; 9]],
        w: f64,
        x: &[f64],
        out: &mut [f64],
    ) {
        let rows = row_ptr.len() - 1;
        let (x, out) = (&x[..3 * rows], &mut out[..3 * rows]);
        let mask = _mm256_setr_epi64x(-1, -1, -1, 0);
        for i in 0..rows {
            let range = row_ptr[i]..row_ptr[i + 1];
            let (mut a, mut b) = (_mm256_setzero_pd(), _mm256_setzero_pd());
            let mut c = 0.0f64;
            let wx = [w * x[3 * i], w * x[3 * i + 1], w * x[3 * i + 2]].map(|v| _mm256_set1_pd(v));
            for (&col, block) in columns[range.clone()].iter().zip(&values[range]) {
                let at = 3 * col as usize;
                let xs = &x[at..at + 3];
                let v = _mm256_maskload_pd(xs.as_ptr(), mask);
                let p = block.as_ptr();
                a = _mm256_fmadd_pd(_mm256_loadu_pd(p), _mm256_permute4x64_pd(v, 0b00_10_01_00), a);
                b = _mm256_fmadd_pd(_mm256_loadu_pd(p.add(4)), _mm256_permute4x64_pd(v, 0b01_00_10_01), b);
                c = block[8].mul_add(xs[2], c);
                if SYMMETRIC && at != 3 * i {
                    // B^T x_i: the rows of B (the third read through the mask: it ends the
                    // block) times the entries of x_i; lane 3 is not stored.
                    let t = _mm256_mul_pd(_mm256_loadu_pd(p), wx[0]);
                    let t = _mm256_fmadd_pd(_mm256_loadu_pd(p.add(3)), wx[1], t);
                    let t = _mm256_fmadd_pd(_mm256_maskload_pd(p.add(6), mask), wx[2], t);
                    let o = out[at..at + 3].as_mut_ptr();
                    _mm256_maskstore_pd(o, mask, _mm256_add_pd(_mm256_maskload_pd(o, mask), t));
                }
            }
            let (mut sa, mut sb) = ([0.0f64; 4], [0.0f64; 4]);
            _mm256_storeu_pd(sa.as_mut_ptr(), a);
            _mm256_storeu_pd(sb.as_mut_ptr(), b);
            let o = &mut out[3 * i..3 * i + 3];
            o[0] = w.mul_add((sa[0] + sa[1]) + sa[2], o[0]);
            o[1] = w.mul_add((sa[3] + sb[0]) + sb[1], o[1]);
            o[2] = w.mul_add((sb[2] + sb[3]) + c, o[2]);
        }
    }

    /// For nodes whose three coordinates are all kept: out[v][c] = sum over the nodes of
    /// rows[3 node + c] x_v[3 node + c] (rows of four; v < 3, c < 3), in nine vectors of
    /// sums over the nodes in order.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(crate) unsafe fn node_row_sums(rows: &[[f64; 4]], vectors: [&[f64]; 3]) -> [[[f64; 4]; 3]; 3] {
        let n = rows.len() - rows.len() % 3;
        let [x0, x1, x2] = vectors.map(|v| &v[..n]);
        let mut acc = [_mm256_setzero_pd(); 9];
        for i in (0..n).step_by(3) {
            for c in 0..3 {
                let r = _mm256_loadu_pd(rows[i + c].as_ptr());
                for (v, x) in [x0, x1, x2].iter().enumerate() {
                    acc[3 * v + c] = _mm256_fmadd_pd(r, _mm256_set1_pd(x[i + c]), acc[3 * v + c]);
                }
            }
        }
        let mut out = [[[0.0f64; 4]; 3]; 3];
        for (k, a) in acc.iter().enumerate() {
            _mm256_storeu_pd(out[k / 3][k % 3].as_mut_ptr(), *a);
        }
        out
    }

    /// out[..rows] += w A x for A column-major (rows x x.len()): rows in blocks of sixteen
    /// (four vectors of sums kept in registers over all columns), then of four, then one at a
    /// time; each sum runs over the columns in order.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(crate) unsafe fn dense_mul_add(rows: usize, a: &[f64], w: f64, x: &[f64], out: &mut [f64]) {
        let cols = x.len();
        let (a, out) = (&a[..rows * cols], &mut out[..rows]);
        let (ap, op) = (a.as_ptr(), out.as_mut_ptr());
        let mut r = 0;
        while r + 16 <= rows {
            let mut acc = [
                _mm256_loadu_pd(op.add(r)),
                _mm256_loadu_pd(op.add(r + 4)),
                _mm256_loadu_pd(op.add(r + 8)),
                _mm256_loadu_pd(op.add(r + 12)),
            ];
            for (c, &xc) in x.iter().enumerate() {
                let v = _mm256_set1_pd(w * xc);
                let column = ap.add(c * rows + r);
                for (k, s) in acc.iter_mut().enumerate() {
                    *s = _mm256_fmadd_pd(_mm256_loadu_pd(column.add(4 * k)), v, *s);
                }
            }
            for (k, s) in acc.iter().enumerate() {
                _mm256_storeu_pd(op.add(r + 4 * k), *s);
            }
            r += 16;
        }
        while r + 4 <= rows {
            let mut s = _mm256_loadu_pd(op.add(r));
            for (c, &xc) in x.iter().enumerate() {
                s = _mm256_fmadd_pd(_mm256_loadu_pd(ap.add(c * rows + r)), _mm256_set1_pd(w * xc), s);
            }
            _mm256_storeu_pd(op.add(r), s);
            r += 4;
        }
        for (i, o) in out.iter_mut().enumerate().skip(r) {
            for (c, &xc) in x.iter().enumerate() {
                *o = a[c * rows + i].mul_add(w * xc, *o);
            }
        }
    }

    /// [`super::increment_ratios`]: per lane the best ratio as a fraction (numerator,
    /// denominator, index), a / b > n / m tested as a m > n b, in two sets of lanes (eight
    /// entries a round: the test waits for the last round's choice, a chain of dependent
    /// operations); the lanes and the last entries compared at the end by their ratios (the
    /// first index of equal ones).
    #[target_feature(enable = "avx2,fma")]
    pub(crate) unsafe fn increment_ratios(d: &[f64], q: &[f64], w: f64) -> (f64, usize, f64) {
        use std::arch::x86_64::{
            _mm256_andnot_pd, _mm256_blendv_pd, _mm256_cmp_pd, _mm256_max_pd, _mm256_setr_pd, _CMP_GT_OQ,
        };
        let n = d.len();
        let q = &q[..n];
        let (sign, one, zero) = (_mm256_set1_pd(-0.0), _mm256_set1_pd(1.0), _mm256_setzero_pd());
        let (tiny, weight) = (_mm256_set1_pd(1e-14), _mm256_set1_pd(w));
        let (four, eight) = (_mm256_set1_pd(4.0), _mm256_set1_pd(8.0));
        // Per set: ratio numerator, denominator, index; relative increment numerator,
        // denominator (named, so that they stay in registers).
        let (mut rn0, mut rd0, mut ra0, mut pn0, mut pd0) = (zero, one, zero, zero, one);
        let (mut rn1, mut rd1, mut ra1, mut pn1, mut pd1) = (zero, one, zero, zero, one);
        let mut index = _mm256_setr_pd(0.0, 1.0, 2.0, 3.0);
        macro_rules! round {
            ($k:expr, $index:expr, $rn:ident, $rd:ident, $ra:ident, $pn:ident, $pd:ident) => {{
                let a = _mm256_andnot_pd(sign, _mm256_loadu_pd(d.as_ptr().add($k)));
                let size = _mm256_max_pd(_mm256_andnot_pd(sign, _mm256_loadu_pd(q.as_ptr().add($k))), one);
                let b = _mm256_add_pd(weight, _mm256_mul_pd(tiny, size));
                let better = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(a, $rd), _mm256_mul_pd($rn, b));
                $rn = _mm256_blendv_pd($rn, a, better);
                $rd = _mm256_blendv_pd($rd, b, better);
                $ra = _mm256_blendv_pd($ra, $index, better);
                let further = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(a, $pd), _mm256_mul_pd($pn, size));
                $pn = _mm256_blendv_pd($pn, a, further);
                $pd = _mm256_blendv_pd($pd, size, further);
            }};
        }
        let whole = n - n % 4;
        let mut k = 0;
        while k + 8 <= whole {
            round!(k, index, rn0, rd0, ra0, pn0, pd0);
            round!(k + 4, _mm256_add_pd(index, four), rn1, rd1, ra1, pn1, pd1);
            index = _mm256_add_pd(index, eight);
            k += 8;
        }
        if k < whole {
            round!(k, index, rn0, rd0, ra0, pn0, pd0);
        }
        let best = [[rn0, rd0, ra0, pn0, pd0], [rn1, rd1, ra1, pn1, pd1]];
        let lanes = |v: __m256d| {
            let mut out = [0.0f64; 4];
            _mm256_storeu_pd(out.as_mut_ptr(), v);
            out
        };
        let (mut worst, mut at, mut position) = (0.0f64, 0usize, 0.0f64);
        for set in &best {
            let [rn, rd, ra, pn, pd] = set.map(lanes);
            for lane in 0..4 {
                let (v, k) = (rn[lane] / rd[lane], ra[lane] as usize);
                if v > worst || (v == worst && v > 0.0 && k < at) {
                    (worst, at) = (v, k);
                }
                position = position.max(pn[lane] / pd[lane]);
            }
        }
        super::increment_ratios_portable(d, q, w, whole, (worst, at, position))
    }

    /// Dot products of four rows (each at least as long as y) with y: two vectors of four
    /// partial sums per row, one load of y for the four rows. (No closures in these kernels:
    /// they do not inherit the target features, and were calls, not inlined.)
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(super) unsafe fn dot4(rows: [&[f64]; 4], y: &[f64]) -> [f64; 4] {
        let n = y.len();
        let rows = [&rows[0][..n], &rows[1][..n], &rows[2][..n], &rows[3][..n]];
        let (yp, rp) = (y.as_ptr(), [rows[0].as_ptr(), rows[1].as_ptr(), rows[2].as_ptr(), rows[3].as_ptr()]);
        let mut acc: [__m256d; 8] = [_mm256_setzero_pd(); 8];
        let mut j = 0;
        while j + 8 <= n {
            let (y0, y1) = (_mm256_loadu_pd(yp.add(j)), _mm256_loadu_pd(yp.add(j + 4)));
            for r in 0..4 {
                acc[2 * r] = _mm256_fmadd_pd(_mm256_loadu_pd(rp[r].add(j)), y0, acc[2 * r]);
                acc[2 * r + 1] = _mm256_fmadd_pd(_mm256_loadu_pd(rp[r].add(j + 4)), y1, acc[2 * r + 1]);
            }
            j += 8;
        }
        if j + 4 <= n {
            let y0 = _mm256_loadu_pd(yp.add(j));
            for r in 0..4 {
                acc[2 * r] = _mm256_fmadd_pd(_mm256_loadu_pd(rp[r].add(j)), y0, acc[2 * r]);
            }
            j += 4;
        }
        // [sum acc_0, sum acc_1, sum acc_2, sum acc_3] from the pairs of accumulators.
        let (s0, s1) = (_mm256_add_pd(acc[0], acc[1]), _mm256_add_pd(acc[2], acc[3]));
        let (s2, s3) = (_mm256_add_pd(acc[4], acc[5]), _mm256_add_pd(acc[6], acc[7]));
        let (h01, h23) = (_mm256_hadd_pd(s0, s1), _mm256_hadd_pd(s2, s3));
        let sums =
            _mm256_add_pd(_mm256_permute2f128_pd(h01, h23, 0x20), _mm256_permute2f128_pd(h01, h23, 0x31));
        let mut out = [0.0f64; 4];
        _mm256_storeu_pd(out.as_mut_ptr(), sums);
        for (k, yk) in y.iter().enumerate().skip(j) {
            for r in 0..4 {
                out[r] = rows[r][k].mul_add(*yk, out[r]);
            }
        }
        out
    }

    /// y -= sum_r x_r rows_r over the length of y (each row at least as long): one load and
    /// one store of y per vector of four for the four rows.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(super) unsafe fn update4(y: &mut [f64], x: [f64; 4], rows: [&[f64]; 4]) {
        let n = y.len();
        let rows = [&rows[0][..n], &rows[1][..n], &rows[2][..n], &rows[3][..n]];
        let rp = [rows[0].as_ptr(), rows[1].as_ptr(), rows[2].as_ptr(), rows[3].as_ptr()];
        let minus: [__m256d; 4] =
            [_mm256_set1_pd(-x[0]), _mm256_set1_pd(-x[1]), _mm256_set1_pd(-x[2]), _mm256_set1_pd(-x[3])];
        let yp = y.as_mut_ptr();
        let mut j = 0;
        while j + 4 <= n {
            let mut v = _mm256_loadu_pd(yp.add(j));
            for r in (0..4).rev() {
                v = _mm256_fmadd_pd(minus[r], _mm256_loadu_pd(rp[r].add(j)), v);
            }
            _mm256_storeu_pd(yp.add(j), v);
            j += 4;
        }
        for (k, yk) in y.iter_mut().enumerate().skip(j) {
            for r in (0..4).rev() {
                *yk = (-x[r]).mul_add(rows[r][k], *yk);
            }
        }
    }
}

/// The dot products of R rows (each at least as long as y) with y, in eight partial sums
/// each (a last vector of four into the first four), with one load of y for all.
#[inline(always)]
fn dot_rows<const FMA: bool, const R: usize>(rows: [&[f64]; R], y: &[f64]) -> [f64; R] {
    let n = y.len();
    let mut s = [[0.0f64; 8]; R];
    let whole8 = n - n % 8;
    for j in (0..whole8).step_by(8) {
        let yv = &y[j..j + 8];
        for r in 0..R {
            let l = &rows[r][j..j + 8];
            for k in 0..8 {
                s[r][k] = mul_add::<FMA>(l[k], yv[k], s[r][k]);
            }
        }
    }
    let mut j = whole8;
    if n - j >= 4 {
        let yv = &y[j..j + 4];
        for r in 0..R {
            let l = &rows[r][j..j + 4];
            for k in 0..4 {
                s[r][k] = mul_add::<FMA>(l[k], yv[k], s[r][k]);
            }
        }
        j += 4;
    }
    for (jj, yj) in y.iter().enumerate().skip(j) {
        for r in 0..R {
            s[r][0] = mul_add::<FMA>(rows[r][jj], *yj, s[r][0]);
        }
    }
    s.map(|s| ((s[0] + s[4]) + (s[2] + s[6])) + ((s[1] + s[5]) + (s[3] + s[7])))
}

/// y -= sum_r x_r rows_r over the length of y (each row at least as long), one load and one
/// store of y for all R rows.
#[inline(always)]
fn update_rows<const FMA: bool, const R: usize>(y: &mut [f64], x: [f64; R], rows: [&[f64]; R]) {
    let n = y.len();
    let rows: [&[f64]; R] = rows.map(|l| &l[..n]);
    for (j, yj) in y.iter_mut().enumerate() {
        let mut v = *yj;
        for r in (0..R).rev() {
            v = mul_add::<FMA>(-x[r], rows[r][j], v);
        }
        *yj = v;
    }
}

/// out[..rows] += w A x for a dense A stored column-major (rows x x.len()), in the AVX2
/// kernel where the CPU has it (the constant matrices of modal bodies, the stacked I_kl).
pub(crate) fn dense_mul_add(rows: usize, a: &[f64], w: f64, x: &[f64], out: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if has_avx2_fma() {
        // SAFETY: the CPU supports AVX2 and FMA (checked above).
        return unsafe { avx2::dense_mul_add(rows, a, w, x, out) };
    }
    dense_mul_add_portable(rows, a, w, x, out);
}

/// [`dense_mul_add`] in portable code, column by column.
fn dense_mul_add_portable(rows: usize, a: &[f64], w: f64, x: &[f64], out: &mut [f64]) {
    if rows == 0 {
        return;
    }
    let out = &mut out[..rows];
    for (column, &xc) in a.chunks_exact(rows).zip(x) {
        let v = w * xc;
        for (o, a) in out.iter_mut().zip(column) {
            *o += a * v;
        }
    }
}

/// out[4 i + k] = sum over the entries (r, m) of column i of the CSC matrix (`col_ptr`,
/// `row_idx`, `values`) of m x[4 r + k], k < 4: for a symmetric matrix of nodes, its products
/// with three node-wise vectors padded to four (row i gathered from column i), in the AVX2
/// kernel where the CPU has it.
pub(crate) fn node_products4(
    col_ptr: &[usize],
    row_idx: &[usize],
    values: &[f64],
    x: &[f64],
    out: &mut [f64],
) {
    #[cfg(target_arch = "x86_64")]
    if has_avx2_fma() {
        // SAFETY: the CPU supports AVX2 and FMA (checked above).
        return unsafe { avx2::node_products4(col_ptr, row_idx, values, x, out) };
    }
    node_products4_portable(col_ptr, row_idx, values, x, out);
}

/// [`node_products4`] in portable code.
fn node_products4_portable(col_ptr: &[usize], row_idx: &[usize], values: &[f64], x: &[f64], out: &mut [f64]) {
    for (col, node_out) in out.chunks_exact_mut(4).enumerate().take(col_ptr.len() - 1) {
        let mut sum = [0.0f64; 4];
        for e in col_ptr[col]..col_ptr[col + 1] {
            let (row, m) = (row_idx[e], values[e]);
            for (s, v) in sum.iter_mut().zip(&x[4 * row..4 * row + 4]) {
                *s += m * v;
            }
        }
        node_out.copy_from_slice(&sum);
    }
}

/// The loop of the Newton increment norm (`generalized_alpha::newton::increment_norm`): the largest
/// ratio |d_k| / (w + 1e-14 max(1, |q_k|)) with its index, and the largest |d_k| / max(1,
/// |q_k|) (NaN entries are passed over; 0 for none), in the AVX2 kernel where the CPU has it.
/// Both codes divide only at the entries that may raise a maximum; the kernel keeps each
/// lane's best ratio as a fraction and compares by products, so that it may take another of
/// two ratios within a rounding of each other.
pub(crate) fn increment_ratios(d: &[f64], q: &[f64], w: f64) -> (f64, usize, f64) {
    #[cfg(target_arch = "x86_64")]
    if has_avx2_fma() {
        // SAFETY: the CPU supports AVX2 and FMA (checked above).
        return unsafe { avx2::increment_ratios(d, q, w) };
    }
    increment_ratios_portable(d, q, w, 0, (0.0, 0, 0.0))
}

/// [`increment_ratios`] in portable code, over the entries from `first` on, continuing from
/// `start` (largest ratio, its index, largest relative increment).
fn increment_ratios_portable(
    d: &[f64],
    q: &[f64],
    w: f64,
    first: usize,
    start: (f64, usize, f64),
) -> (f64, usize, f64) {
    let (mut worst, mut at, mut position) = start;
    for (k, (dq, q)) in d.iter().zip(q).enumerate().skip(first) {
        let (a, size) = (dq.abs(), q.abs().max(1.0));
        let b = w + 1e-14 * size;
        if a > worst * b {
            let v = a / b;
            if v > worst {
                (worst, at) = (v, k);
            }
        }
        if a > position * size {
            position = position.max(a / size);
        }
    }
    (worst, at, position)
}

/// The dot products of four rows (each at least as long as y) with y, in the AVX2 kernel
/// where the CPU has it.
pub(crate) fn dot4(rows: [&[f64]; GROUP], y: &[f64]) -> [f64; GROUP] {
    if has_avx2_fma() {
        group_dot::<true>(rows, y)
    } else {
        group_dot::<false>(rows, y)
    }
}

/// y -= sum_r x_r rows_r over the length of y (each row at least as long), in the AVX2
/// kernel where the CPU has it.
pub(crate) fn update4(y: &mut [f64], x: [f64; GROUP], rows: [&[f64]; GROUP]) {
    if has_avx2_fma() {
        group_update::<true>(y, x, rows)
    } else {
        group_update::<false>(y, x, rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{assert_all_close, assert_close};

    #[test]
    fn dense_products_agree_with_plain_sums() {
        // Row counts through the blocks of sixteen and four and the single rows, column
        // counts from none on; out starts nonzero and past `rows` stays untouched.
        for rows in [0usize, 1, 3, 4, 5, 15, 16, 17, 21, 36, 144] {
            for cols in [0usize, 1, 2, 7, 16] {
                let a: Vec<f64> = (0..rows * cols).map(|k| ((k * 37) % 11) as f64 - 5.0).collect();
                let x: Vec<f64> = (0..cols).map(|c| 0.5 * c as f64 - 1.25).collect();
                let start: Vec<f64> = (0..rows + 2).map(|i| i as f64 * 0.125).collect();
                let w = -0.75;
                let exact: Vec<f64> = (0..rows)
                    .map(|i| start[i] + w * (0..cols).map(|c| a[c * rows + i] * x[c]).sum::<f64>())
                    .collect();
                let (mut fast, mut plain) = (start.clone(), start.clone());
                dense_mul_add(rows, &a, w, &x, &mut fast);
                dense_mul_add_portable(rows, &a, w, &x, &mut plain);
                for out in [&fast, &plain] {
                    assert_all_close(
                        &out[..rows],
                        &exact,
                        1e-12,
                        1e-12,
                        format_args!("{rows} x {cols}, row"),
                    );
                    assert_eq!(&out[rows..], &start[rows..]);
                }
            }
        }
    }

    #[test]
    fn increment_ratios_agree_with_the_portable_loop() {
        // Lengths with 0 to 3 entries after the groups of four, the largest ratio and the
        // largest relative increment anywhere, NaN passed over, an all-zero increment.
        for n in [0usize, 1, 3, 4, 5, 8, 11, 17] {
            for at in 0..n.max(1) {
                let mut d: Vec<f64> = (0..n).map(|k| ((k * 7 % 5) as f64 - 2.0) * 1e-3).collect();
                let q: Vec<f64> = (0..n).map(|k| ((k * 3 % 7) as f64 - 3.0) * 0.7).collect();
                if n > 0 {
                    d[at] = 0.5;
                    d[(at + 1) % n] = f64::NAN;
                }
                for d in [d.clone(), vec![0.0; n]] {
                    let expected = super::increment_ratios_portable(&d, &q, 2e-6, 0, (0.0, 0, 0.0));
                    let (worst, k, position) = super::increment_ratios(&d, &q, 2e-6);
                    assert_close(worst, expected.0, 1e-15, 0.0, format_args!("{n} {at}: worst ratio"));
                    assert_eq!(k, expected.1, "{n} {at}");
                    assert_close(position, expected.2, 1e-15, 0.0, format_args!("{n} {at}: position"));
                    if n > 1 && d[at] != 0.0 {
                        assert_eq!(k, at);
                    }
                }
            }
        }
    }

    #[test]
    fn node_products_of_four_agree_with_plain_sums() {
        // Columns of none to five entries, rows in any order, repeated rows.
        let col_ptr = [0, 2, 2, 5, 6, 11];
        let row_idx = [1, 3, 0, 2, 4, 4, 0, 1, 2, 3, 3];
        let values: Vec<f64> = (0..11).map(|k| 0.5 + 0.25 * k as f64).collect();
        let x: Vec<f64> = (0..20).map(|k| ((k * 7) % 11) as f64 - 4.5).collect();
        let mut plain = vec![0.0; 20];
        for col in 0..5 {
            for e in col_ptr[col]..col_ptr[col + 1] {
                for k in 0..4 {
                    plain[4 * col + k] += values[e] * x[4 * row_idx[e] + k];
                }
            }
        }
        for kernel in [node_products4, node_products4_portable] {
            let mut out = vec![f64::NAN; 20];
            kernel(&col_ptr, &row_idx, &values, &x, &mut out);
            assert_all_close(&out, &plain, 1e-14, 1e-14, "node products");
        }
    }

    #[test]
    fn group_kernels_agree_with_plain_sums() {
        // Every length from 0 to 21 (the 8- and 4-wide loops and the scalar tail), rows
        // longer than y, in the dispatching and the portable kernels.
        for n in 0..22usize {
            let rows: Vec<Vec<f64>> =
                (0..4).map(|r| (0..n + 3).map(|j| ((r * 31 + j * 17) % 13) as f64 - 6.0).collect()).collect();
            let y: Vec<f64> = (0..n).map(|j| 0.25 * j as f64 - 1.0).collect();
            let group = [&rows[0][..], &rows[1][..], &rows[2][..], &rows[3][..]];
            let exact: Vec<f64> = rows.iter().map(|r| r.iter().zip(&y).map(|(a, b)| a * b).sum()).collect();
            for sums in [dot4(group, &y), dot_rows::<false, GROUP>(group, &y)] {
                assert_all_close(&sums, &exact, 1e-12, 1e-12, format_args!("n = {n}: dot"));
            }
            let x = [0.5, -1.5, 2.0, 0.25];
            let expected: Vec<f64> =
                (0..n).map(|j| y[j] - (0..4).map(|r| x[r] * rows[r][j]).sum::<f64>()).collect();
            let (mut a, mut b) = (y.clone(), y.clone());
            update4(&mut a, x, group);
            update_rows::<false, GROUP>(&mut b, x, group);
            for v in [&a, &b] {
                assert_all_close(v, &expected, 1e-12, 1e-12, format_args!("n = {n}: update"));
            }
        }
    }
}
