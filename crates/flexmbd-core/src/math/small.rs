//! Fixed-size dense matrix helpers over plain arrays (`[[f64; C]; R]`, row-major), used by
//! the Euler-parameter kernels for 3 x 4 Jacobians and 4 x 4 Hessians.

/// Matrix product `a b`.
pub fn matmul<const R: usize, const K: usize, const C: usize>(
    a: &[[f64; K]; R],
    b: &[[f64; C]; K],
) -> [[f64; C]; R] {
    let mut out = [[0.0; C]; R];
    for i in 0..R {
        for k in 0..K {
            let aik = a[i][k];
            for j in 0..C {
                out[i][j] += aik * b[k][j];
            }
        }
    }
    out
}

/// Matrix product `a^T b`.
pub fn tr_matmul<const R: usize, const K: usize, const C: usize>(
    a: &[[f64; K]; R],
    b: &[[f64; C]; R],
) -> [[f64; C]; K] {
    let mut out = [[0.0; C]; K];
    for r in 0..R {
        for i in 0..K {
            let ari = a[r][i];
            for j in 0..C {
                out[i][j] += ari * b[r][j];
            }
        }
    }
    out
}

/// Matrix-vector product `a v`.
pub fn matvec<const R: usize, const C: usize>(a: &[[f64; C]; R], v: &[f64; C]) -> [f64; R] {
    let mut out = [0.0; R];
    for i in 0..R {
        out[i] = (0..C).map(|j| a[i][j] * v[j]).sum();
    }
    out
}

/// Transposed matrix-vector product `a^T v`.
pub fn tr_matvec<const R: usize, const C: usize>(a: &[[f64; C]; R], v: &[f64; R]) -> [f64; C] {
    let mut out = [0.0; C];
    for i in 0..R {
        for j in 0..C {
            out[j] += a[i][j] * v[i];
        }
    }
    out
}

/// Scaled copy `s a`.
pub fn scaled<const R: usize, const C: usize>(a: &[[f64; C]; R], s: f64) -> [[f64; C]; R] {
    let mut out = *a;
    out.iter_mut().flatten().for_each(|x| *x *= s);
    out
}

/// In-place sum `a += s b`.
pub fn add_scaled<const R: usize, const C: usize>(a: &mut [[f64; C]; R], s: f64, b: &[[f64; C]; R]) {
    for i in 0..R {
        for j in 0..C {
            a[i][j] += s * b[i][j];
        }
    }
}
