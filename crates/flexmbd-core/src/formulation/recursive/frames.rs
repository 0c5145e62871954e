//! Joint frames of the tree as hyper-dual numbers: rotations, the frames of the joint types,
//! Cardan angles, and the pose of a joint side.

use super::*;

pub(crate) fn rot(axis: usize, angle: HyperDual) -> HMat {
    let (s, c) = (angle.sin(), angle.cos());
    let (o, z) = (HyperDual::ONE, HyperDual::ZERO);
    match axis {
        0 => [[o, z, z], [z, c, -s], [z, s, c]],
        1 => [[c, z, s], [z, o, z], [-s, z, c]],
        _ => [[c, -s, z], [s, c, z], [z, z, o]],
    }
}

/// The unit vector v in the plane of x and y with (x . v, y . v) a positive multiple of
/// (cos phi, sin phi): the direction an angle driver prescribes when x and y are the
/// (deformed, not exactly orthonormal) axes of its marker i. For orthonormal x, y it is
/// cos phi x + sin phi y.
pub(crate) fn driver_direction(x: &HVec, y: &HVec, phi: HyperDual) -> HVec {
    let (c, s) = (phi.cos(), phi.sin());
    let (g11, g12, g22) = (dot(x, x), dot(x, y), dot(y, y));
    let alpha = g22 * c - g12 * s;
    let beta = g11 * s - g12 * c;
    normalize(&add(&scale(x, alpha), &scale(y, beta)))
}

/// The orthonormal frame [w, z x w, z] with z along `z` and w along the part of `x`
/// perpendicular to it.
pub(crate) fn frame_from_z(z: &HVec, x: &HVec) -> HMat {
    let z = normalize(z);
    let w = normalize(&sub(x, &scale(&z, dot(x, &z))));
    from_columns(&w, &cross(&z, &w), &z)
}

/// The orthonormal frame [v, n x v, n] with n along x x y and v the driver direction of phi.
pub(crate) fn frame_from_plane(x: &HVec, y: &HVec, phi: HyperDual) -> HMat {
    let n = normalize(&cross(x, y));
    let v = driver_direction(x, y, phi);
    from_columns(&v, &cross(&n, &v), &n)
}

/// Orthonormal frames P (global, parent side) and Q (child body frame) with A_child Q = P
/// that satisfy a revolute joint's equations (x_i . z_j = 0, y_i . z_j = 0) and its angle (the
/// driver's) exactly, also for the deformed, not exactly orthonormal axes of markers on
/// deformable bodies. `x_p`: the parent-side marker's global axes; `xb_c`: the child-side
/// marker's axes in the child body frame; `i_parent`: whether marker i is the parent side.
pub(crate) fn revolute_frames(i_parent: bool, x_p: &HMat, xb_c: &HMat, phi: HyperDual) -> (HMat, HMat) {
    if i_parent {
        (
            frame_from_plane(&column(x_p, 0), &column(x_p, 1), phi),
            frame_from_z(&column(xb_c, 2), &column(xb_c, 0)),
        )
    } else {
        (
            frame_from_z(&column(x_p, 2), &column(x_p, 0)),
            frame_from_plane(&column(xb_c, 0), &column(xb_c, 1), phi),
        )
    }
}

/// The revolute's frames with the angle about the common axis fixed by the twist equation
/// x_i . y_j = 0 instead of a coordinate (exact for deformed axes too): fixed and prismatic
/// joints.
pub(crate) fn fixed_frames(i_parent: bool, x_p: &HMat, xb_c: &HMat) -> (HMat, HMat) {
    if i_parent {
        let (x_i, y_i) = (column(x_p, 0), column(x_p, 1));
        let n = normalize(&cross(&x_i, &y_i));
        let e1 = normalize(&x_i);
        let e2 = cross(&n, &e1);
        let q_frame = frame_from_z(&column(xb_c, 2), &column(xb_c, 0));
        let y_j = column(xb_c, 1);
        let (w1, w2) = (dot(&column(&q_frame, 0), &y_j), dot(&column(&q_frame, 1), &y_j));
        let r = (w1 * w1 + w2 * w2).sqrt().recip();
        let v = add(&scale(&e1, w2 * r), &scale(&e2, w1 * r));
        (from_columns(&v, &cross(&n, &v), &n), q_frame)
    } else {
        let z = normalize(&column(x_p, 2));
        let p1 = normalize(&cross(&column(x_p, 1), &z));
        let (x_i, y_i) = (column(xb_c, 0), column(xb_c, 1));
        let n = normalize(&cross(&x_i, &y_i));
        let e1 = normalize(&x_i);
        (from_columns(&p1, &cross(&z, &p1), &z), from_columns(&e1, &cross(&n, &e1), &n))
    }
}

/// The orthonormal frame [x^, z^ x x^, z^] with x^ along `x` and z^ along the part of `z`
/// perpendicular to it.
pub(crate) fn frame_x_first(x: &HVec, z: &HVec) -> HMat {
    let x = normalize(x);
    let z = normalize(&sub(z, &scale(&x, dot(z, &x))));
    from_columns(&x, &cross(&z, &x), &z)
}

/// The orthonormal frame [y^ x z^, y^, z^] with y^ along `y` and z^ along the part of `z`
/// perpendicular to it.
pub(crate) fn frame_y_first(y: &HVec, z: &HVec) -> HMat {
    let y = normalize(y);
    let z = normalize(&sub(z, &scale(&y, dot(z, &y))));
    from_columns(&cross(&y, &z), &y, &z)
}

/// The orthonormal frame [w, z x w, z] of marker axes (f64; see [`frame_from_z`]).
pub(crate) fn orthonormal(axes: &Mat3) -> Mat3 {
    let h = hmat(axes.0);
    Mat3(crate::math::hyper_dual::values(&frame_from_z(&column(&h, 2), &column(&h, 0))))
}

/// Cardan angles (a, b, c) of R = R_x(a) R_y(b) R_z(c).
pub(crate) fn cardan_angles(r: &Mat3) -> Vec<f64> {
    let m = &r.0;
    vec![
        (-m[1][2]).atan2(m[2][2]),
        m[0][2].atan2((m[0][0] * m[0][0] + m[0][1] * m[0][1]).sqrt()),
        (-m[0][1]).atan2(m[0][0]),
    ]
}

/// R_x(a) R_y(b) R_z(c).
pub(crate) fn cardan(a: HyperDual, b: HyperDual, c: HyperDual) -> HMat {
    mul_mat(&mul_mat(&rot(0, a), &rot(1, b)), &rot(2, c))
}

impl Side {
    /// The side's marker on `model`'s marker `m`.
    pub(crate) fn new(model: &Model, m: usize) -> Side {
        let marker = &model.markers[m];
        Side {
            body: marker.body.0,
            position: marker.position,
            rotation: marker.rotation,
            elastic: marker.elastic.clone(),
        }
    }

    /// Deformation (u - u0, theta) in the body frame for the body's elastic coordinates q_f.
    pub(crate) fn deformation(&self, qf: &[HyperDual]) -> [HVec; 2] {
        let mut out = [[HyperDual::ZERO; 3]; 2];
        if let Some(e) = &self.elastic {
            for (j, &idx) in e.indices.iter().enumerate() {
                for i in 0..3 {
                    out[0][i] = out[0][i] + qf[idx] * e.translation.get(i, j);
                    out[1][i] = out[1][i] + qf[idx] * e.rotation.get(i, j);
                }
            }
        }
        out
    }

    /// Body-frame position and axes for the deformation `d`.
    pub(crate) fn local_frame(&self, d: &[HVec; 2]) -> (HVec, HMat) {
        if self.elastic.is_none() {
            return (hvec(self.position.0), hmat(self.rotation.0));
        }
        let u = add(&hvec(self.position.0), &d[0]);
        let a = hmat(self.rotation.0);
        let cols: [HVec; 3] = std::array::from_fn(|k| {
            let c = column(&a, k);
            add(&c, &cross(&d[1], &c))
        });
        (u, from_columns(&cols[0], &cols[1], &cols[2]))
    }
}

/// The state of the bodies as hyper-dual numbers: rotation matrix and origin.
pub(crate) type Pose = (HMat, HVec);
