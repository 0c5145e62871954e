//! The kinematics of the tree: the poses of the bodies from the joint and elastic
//! coordinates, their rates, the influence matrices B (seed eq. 31) and the rebasing of
//! Cardan angles.

use super::*;

impl Tree {
    /// Number of coordinates: joint coordinates (prescribed ones included) and elastic ones.
    pub fn coordinate_count(&self) -> usize {
        self.coordinate_count
    }

    /// Number of joint coordinates (prescribed ones included).
    pub fn joint_coordinate_count(&self) -> usize {
        self.joint_coordinate_count
    }

    /// Number of free (integrated) coordinates.
    pub fn free_count(&self) -> usize {
        self.free.len()
    }

    /// The body state at time `time` for the free coordinates `p` and rates `pd`, the
    /// prescribed ones from their drivers.
    pub fn evaluate(&self, model: &Model, time: f64, p: &[f64], pd: &[f64]) -> Result<TreeState> {
        let n = model.coordinate_count;
        let (full_p, full_pd, pdd) = self.full_coordinates(model, time, p, pd)?;
        let (coordinates, velocities, gamma) = self.state_with(n, &full_p, &full_pd, &pdd);
        let influence = self.influence_columns(n, &full_p, &self.free);
        Ok(TreeState { coordinates, velocities, gamma, influence })
    }

    /// The body state at time `time` for the free coordinates `p` and rates `pd`, with the
    /// influence coefficients in the structure of seed eq. 33 instead of a dense B: H_pp over
    /// the reference rows and, for H_pf, the derivatives of the reference coordinates with
    /// respect to each deformed joint marker's deformation (H_pf = sum over the markers of
    /// D_m S_m). Its cost does not depend on the number of elastic coordinates.
    pub fn structured(&self, model: &Model, time: f64, p: &[f64], pd: &[f64]) -> Result<StructuredState> {
        let n = model.coordinate_count;
        let (full_p, full_pd, pdd) = self.full_coordinates(model, time, p, pd)?;
        let (coordinates, velocities, gamma) = self.state_with(n, &full_p, &full_pd, &pdd);
        let free_joints: Vec<usize> =
            self.free.iter().copied().filter(|&c| c < self.joint_coordinate_count).collect();
        let joints = self.joint_columns(n, &full_p, &free_joints);
        let rows = &self.reference_rows;
        let joint_influence = Mat::from_fn(rows.len(), free_joints.len(), |i, k| joints[(rows[i], k)]);
        let markers = self
            .marker_derivatives(n, &full_p)
            .into_iter()
            .map(|d| Mat::from_fn(rows.len(), 6, |i, c| d[(rows[i], c)]))
            .collect();
        Ok(StructuredState { coordinates, velocities, gamma, joint_influence, markers })
    }

    /// Spherical and free joints whose Cardan angle b is beyond `limit` (rad) from zero, near
    /// the singularity at +-90 degrees, are rebased: R_0 absorbs the current angles, which
    /// restart at zero, and the angle rates are transformed so that the relative angular
    /// velocity is unchanged (theta_dot' = R^T E(a, b) theta_dot, E the map from the Cardan
    /// rates to the angular velocity in the parent-side frame). The body state does not change.
    /// `p` and `pd` are the free coordinates and rates; returns the rebased joints' names.
    pub fn rebase(&mut self, model: &Model, p: &mut [f64], pd: &mut [f64], limit: f64) -> Vec<String> {
        let mut rebased = Vec::new();
        let position = |c: usize, free: &[usize]| free.iter().position(|&x| x == c);
        for joint in self.joints.iter_mut() {
            let angles = match joint.kind {
                TreeJointKind::Spherical => joint.first,
                TreeJointKind::Free => joint.first + 3,
                _ => continue,
            };
            let Some(k) = position(angles, &self.free) else { continue };
            let (a, b, c) = (p[k], p[k + 1], p[k + 2]);
            if b.abs() <= limit {
                continue;
            }
            let h = |x: f64| HyperDual::constant(x);
            let r = Mat3(values(&cardan(h(a), h(b), h(c))));
            // E(a, b): columns e_x, R_x(a) e_y, R_x(a) R_y(b) e_z.
            let rx = Mat3(values(&rot(0, h(a))));
            let rxy = rx.mul_mat(&Mat3(values(&rot(1, h(b)))));
            let omega = Vec3::unit(0) * pd[k] + rx.column(1) * pd[k + 1] + rxy.column(2) * pd[k + 2];
            let rates = r.tr_mul_vec(&omega);
            joint.base = joint.base.mul_mat(&r);
            for i in 0..3 {
                p[k + i] = 0.0;
                pd[k + i] = rates[i];
            }
            let body = &model.bodies[joint.child.body].name;
            rebased.push(if joint.kind == TreeJointKind::Free {
                format!("free joint of body '{body}'")
            } else {
                format!("spherical joint of body '{body}'")
            });
        }
        rebased
    }

    /// The free rates p_dot whose body velocities are `qd` (which must be consistent with the
    /// tree joints and drivers at `time`): the elastic rates are entries of q_dot; the joint
    /// rates solve H_pp p_dot_j = q_dot_r - H_pf qf_dot - (the prescribed part), a
    /// least-squares problem of the reference rows' size.
    pub fn initial_rates(&self, model: &Model, time: f64, p: &[f64], qd: &[f64]) -> Result<Vec<f64>> {
        let st = self.structured(model, time, p, &vec![0.0; p.len()])?;
        let nj = self.free_joint_count();
        let mut pd = vec![0.0; p.len()];
        for (body, first, count) in self.elastic_blocks() {
            let o = self.offsets[body] + 7;
            pd[first..first + count].copy_from_slice(&qd[o..o + count]);
        }
        let rows = &self.reference_rows;
        let mut rhs: Vec<f64> = rows.iter().map(|&r| qd[r] - st.velocities[r]).collect();
        for ((body, shape), d) in self.deformed_markers().into_iter().zip(&st.markers) {
            let o = self.offsets[body] + 7;
            let mut rate = [0.0; 6];
            for (j, &idx) in shape.indices.iter().enumerate() {
                for c in 0..3 {
                    rate[c] += shape.translation.get(c, j) * qd[o + idx];
                    rate[3 + c] += shape.rotation.get(c, j) * qd[o + idx];
                }
            }
            for (i, value) in rhs.iter_mut().enumerate() {
                *value -= (0..6).map(|c| d[(i, c)] * rate[c]).sum::<f64>();
            }
        }
        let joints = crate::linalg::partition::minimum_norm_solve(st.joint_influence.as_ref(), &rhs, 1e-12);
        pd[..nj].copy_from_slice(&joints);
        Ok(pd)
    }

    /// The q indices of the bodies' reference coordinates (the rows r of seed eq. 33), in body
    /// order.
    pub fn reference_rows(&self) -> &[usize] {
        &self.reference_rows
    }

    /// Number of free joint coordinates (the free coordinates start with them; the elastic
    /// coordinates follow).
    pub fn free_joint_count(&self) -> usize {
        self.free.iter().filter(|&&c| c < self.joint_coordinate_count).count()
    }

    /// The deformable bodies: (body, index of its first elastic coordinate among the free
    /// coordinates, count).
    pub fn elastic_blocks(&self) -> Vec<(usize, usize, usize)> {
        let shift = self.free_joint_count();
        self.elastic
            .iter()
            .map(|e| (e.body, shift + e.first - self.joint_coordinate_count, e.count))
            .collect()
    }

    /// The deformed joint markers (the order of [`StructuredState::markers`]): body and shape.
    pub fn deformed_markers(&self) -> Vec<(usize, &MarkerElastic)> {
        self.joints
            .iter()
            .flat_map(|j| [&j.parent, &j.child])
            .filter_map(|side| side.elastic.as_ref().map(|e| (side.body, e)))
            .collect()
    }

    /// Full p, p_dot and the prescribed p_dd from the free coordinates and the drivers.
    pub(crate) fn full_coordinates(
        &self,
        model: &Model,
        time: f64,
        p: &[f64],
        pd: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let np = self.coordinate_count;
        let (mut full_p, mut full_pd, mut pdd) = (vec![0.0; np], vec![0.0; np], vec![0.0; np]);
        for (k, &c) in self.free.iter().enumerate() {
            full_p[c] = p[k];
            full_pd[c] = pd[k];
        }
        for presc in &self.prescribed {
            let [f, fd, fdd] = model.joints[presc.driver].driver_values(time)?;
            full_p[presc.coordinate] = presc.sign * f;
            full_pd[presc.coordinate] = presc.sign * fd;
            pdd[presc.coordinate] = presc.sign * fdd;
        }
        Ok((full_p, full_pd, pdd))
    }

    /// Poses of all bodies for the joint coordinates `p` (hyper-dual) and the deformation of
    /// each joint's markers (`deformation[joint] = [parent side, child side]`).
    pub(crate) fn poses(&self, p: &[HyperDual], deformation: &[[[HVec; 2]; 2]]) -> Vec<Pose> {
        let mut poses: Vec<Pose> = vec![(HIDENTITY, [HyperDual::ZERO; 3]); self.offsets.len()];
        for (joint, d) in self.joints.iter().zip(deformation) {
            poses[joint.child.body] = joint_pose(joint, &poses[joint.parent.body], p, d);
        }
        poses
    }

    /// The poses of `base` (all bodies, at `p` and `deformation`) with those of the bodies
    /// that joint `start` and the joints beyond it move placed again, at the hyper-dual `p`
    /// and `deformation` that differ from `base`'s only in joint `start`'s coordinates or
    /// marker deformations; and which bodies moved. The joints before `start` and those not
    /// beyond it keep their bodies' poses: a pass over a subtree instead of the whole tree.
    pub(crate) fn poses_beyond(
        &self,
        base: &[Pose],
        start: usize,
        p: &[HyperDual],
        deformation: &[[[HVec; 2]; 2]],
    ) -> (Vec<Pose>, Vec<bool>) {
        let mut poses = base.to_vec();
        let mut moved = vec![false; poses.len()];
        for (k, (joint, d)) in self.joints.iter().zip(deformation).enumerate().skip(start) {
            if k == start || moved[joint.parent.body] {
                poses[joint.child.body] = joint_pose(joint, &poses[joint.parent.body], p, d);
                moved[joint.child.body] = true;
            }
        }
        (poses, moved)
    }

    /// The joint whose coordinates include the joint coordinate `k` (p's full layout): the
    /// joints take their coordinates one after the other in tree order, so it is the last
    /// joint that starts at or before `k`.
    pub(super) fn joint_of_coordinate(&self, k: usize) -> usize {
        self.joints.iter().rposition(|j| j.first <= k).expect("a joint coordinate belongs to a joint")
    }

    /// Writes the derivatives (e1) of the reference coordinates of the `moved` bodies at
    /// `poses` into column `col` of `b` (the other bodies' are zero).
    fn influence_column(&self, poses: &[Pose], moved: &[bool], b: &mut Mat<f64>, col: usize) {
        for (body, (a, r)) in poses.iter().enumerate().skip(1) {
            if !moved[body] {
                continue;
            }
            let o = self.offsets[body];
            for i in 0..3 {
                b[(o + i, col)] = r[i].e1;
            }
            if !self.point_masses[body] {
                let e = euler_parameters(a, &self.reference_parameters[body]);
                for i in 0..4 {
                    b[(o + 3 + i, col)] = e[i].e1;
                }
            }
        }
    }
}

/// The pose of `joint`'s child body from its parent body's pose `parent`, the joint and
/// elastic coordinates `p` (hyper-dual) and the deformation `d` of the joint's markers
/// ([parent side, child side]).
pub(super) fn joint_pose(joint: &TreeJoint, parent: &Pose, p: &[HyperDual], d: &[[HVec; 2]; 2]) -> Pose {
    {
        {
            let (a_p, r_p) = *parent;
            let (u_p, xb_p) = joint.parent.local_frame(&d[0]);
            let (u_c, xb_c) = joint.child.local_frame(&d[1]);
            let x_p = mul_mat(&a_p, &xb_p);
            let o_p = add(&r_p, &mul_vec(&a_p, &u_p));
            let f = joint.first;
            let (rotation, o_c) = match joint.kind {
                // Undeformed markers are orthonormal: the frames below reduce to these.
                TreeJointKind::Revolute if !joint.deformed => {
                    let angle = if joint.i_parent { p[f] } else { -p[f] };
                    (mul_transpose(&mul_mat(&x_p, &rot(2, angle)), &xb_c), o_p)
                }
                TreeJointKind::Fixed if !joint.deformed => (mul_transpose(&x_p, &xb_c), o_p),
                TreeJointKind::Revolute => {
                    let (p_frame, q_frame) = revolute_frames(joint.i_parent, &x_p, &xb_c, p[f]);
                    (mul_transpose(&p_frame, &q_frame), o_p)
                }
                TreeJointKind::Fixed => {
                    let (p_frame, q_frame) = fixed_frames(joint.i_parent, &x_p, &xb_c);
                    (mul_transpose(&p_frame, &q_frame), o_p)
                }
                TreeJointKind::Prismatic | TreeJointKind::Cylindrical if joint.deformed => {
                    // Orientation: the fixed joint's frames (prismatic) or the revolute's
                    // (cylindrical); translation along the normal n of the plane of x_i, y_i
                    // (d . x_i = 0, d . y_i = 0) with z_i . d equal to the coordinate.
                    let (p_frame, q_frame) = if joint.kind == TreeJointKind::Prismatic {
                        fixed_frames(joint.i_parent, &x_p, &xb_c)
                    } else {
                        revolute_frames(joint.i_parent, &x_p, &xb_c, p[f])
                    };
                    let s = p[if joint.kind == TreeJointKind::Prismatic { f } else { f + 1 }];
                    let origin = if joint.i_parent {
                        let n = normalize(&cross(&column(&x_p, 0), &column(&x_p, 1)));
                        add(&o_p, &scale(&n, s / dot(&column(&x_p, 2), &n)))
                    } else {
                        // d = r_j - r_i along A_child n_bar = z_j (unit).
                        let n = normalize(&cross(&column(&xb_c, 0), &column(&xb_c, 1)));
                        let z = normalize(&column(&x_p, 2));
                        sub(&o_p, &scale(&z, s / dot(&column(&xb_c, 2), &n)))
                    };
                    (mul_transpose(&p_frame, &q_frame), origin)
                }
                TreeJointKind::Spherical | TreeJointKind::Free => {
                    let p_frame = frame_from_z(&column(&x_p, 2), &column(&x_p, 0));
                    let q_frame = frame_from_z(&column(&xb_c, 2), &column(&xb_c, 0));
                    let (angles, origin) = if joint.kind == TreeJointKind::Free {
                        (f + 3, add(&o_p, &mul_vec(&p_frame, &[p[f], p[f + 1], p[f + 2]])))
                    } else {
                        (f, o_p)
                    };
                    let relative =
                        mul_mat(&hmat(joint.base.0), &cardan(p[angles], p[angles + 1], p[angles + 2]));
                    (mul_transpose(&mul_mat(&p_frame, &relative), &q_frame), origin)
                }
                TreeJointKind::UniversalXY | TreeJointKind::UniversalYX if joint.deformed => {
                    // Orthonormal frames keeping the cross axes exactly: x_i first on the side of
                    // marker i, y_j first on the side of marker j; then F = P R_x(a) R_y(b)
                    // (marker i the parent) keeps F's y perpendicular to x_i, and
                    // F = P R_y(a) R_x(b) (marker j the parent) keeps F's x perpendicular to y_j.
                    let (x_first, y_first) = (
                        |m: &HMat| frame_x_first(&column(m, 0), &column(m, 2)),
                        |m: &HMat| frame_y_first(&column(m, 1), &column(m, 2)),
                    );
                    let (p_frame, relative, q_frame) = if joint.kind == TreeJointKind::UniversalXY {
                        (x_first(&x_p), mul_mat(&rot(0, p[f]), &rot(1, p[f + 1])), y_first(&xb_c))
                    } else {
                        (y_first(&x_p), mul_mat(&rot(1, p[f]), &rot(0, p[f + 1])), x_first(&xb_c))
                    };
                    (mul_transpose(&mul_mat(&p_frame, &relative), &q_frame), o_p)
                }
                TreeJointKind::SphericalPoint => (HIDENTITY, o_p),
                TreeJointKind::FreePoint => (HIDENTITY, add(&o_p, &[p[f], p[f + 1], p[f + 2]])),
                kind => {
                    // Rigid markers: the child marker frame A_pm R_rel, moved along the axis.
                    let axis = mul_vec(&x_p, &hvec(joint.axis.0));
                    let (relative, translation) = match kind {
                        TreeJointKind::Prismatic => (hmat(joint.rotation.0), scale(&axis, p[f])),
                        TreeJointKind::Cylindrical => (rot(2, p[f]), scale(&axis, p[f + 1])),
                        TreeJointKind::UniversalXY => {
                            (mul_mat(&rot(0, p[f]), &rot(1, p[f + 1])), hvec([0.0; 3]))
                        }
                        TreeJointKind::UniversalYX => {
                            (mul_mat(&rot(1, p[f]), &rot(0, p[f + 1])), hvec([0.0; 3]))
                        }
                        _ => (HIDENTITY, hvec([0.0; 3])),
                    };
                    (mul_transpose(&mul_mat(&x_p, &relative), &xb_c), add(&o_p, &translation))
                }
            };
            let origin = sub(&o_c, &mul_vec(&rotation, &u_c));
            (rotation, origin)
        }
    }
}

impl Tree {
    /// Reference coordinates (origin, Euler parameters) of every body as hyper-dual numbers,
    /// in q's layout (the elastic entries are left zero).
    pub(crate) fn reference_coordinates(
        &self,
        n: usize,
        p: &[HyperDual],
        deformation: &[[[HVec; 2]; 2]],
    ) -> Vec<HyperDual> {
        let poses = self.poses(p, deformation);
        let mut q = vec![HyperDual::ZERO; n];
        for (b, (a, r)) in poses.iter().enumerate().skip(1) {
            let o = self.offsets[b];
            q[o..o + 3].copy_from_slice(r);
            if !self.point_masses[b] {
                q[o + 3..o + 7].copy_from_slice(&euler_parameters(a, &self.reference_parameters[b]));
            }
        }
        q
    }

    /// The marker deformations of every joint for elastic coordinates given per p index.
    pub(crate) fn deformations(&self, p: &[HyperDual]) -> Vec<[[HVec; 2]; 2]> {
        let qf = |body: usize| -> &[HyperDual] {
            match self.elastic.iter().find(|e| e.body == body) {
                Some(e) => &p[e.first..e.first + e.count],
                None => &[],
            }
        };
        self.joints
            .iter()
            .map(|j| [j.parent.deformation(qf(j.parent.body)), j.child.deformation(qf(j.child.body))])
            .collect()
    }

    /// Body coordinates q, velocities q_dot and accelerations q_dd at (p, p_dot, p_dd), all of
    /// length `n` (the model's coordinate count), with the elastic accelerations in p_dd taken
    /// zero: q_dd = gamma_B + B p_dd over the joint coordinates.
    pub(crate) fn state_with(
        &self,
        n: usize,
        p: &[f64],
        pd: &[f64],
        pdd: &[f64],
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let ph: Vec<HyperDual> = (0..p.len())
            .map(|k| {
                HyperDual::curve(p[k], pd[k], if k < self.joint_coordinate_count { pdd[k] } else { 0.0 })
            })
            .collect();
        let deformation = self.deformations(&ph);
        let qh = self.reference_coordinates(n, &ph, &deformation);
        let (mut q, mut qd, mut gamma): (Vec<f64>, Vec<f64>, Vec<f64>) = (
            qh.iter().map(|x| x.v).collect(),
            qh.iter().map(|x| x.e1).collect(),
            qh.iter().map(|x| x.e12).collect(),
        );
        for e in &self.elastic {
            let o = self.offsets[e.body] + 7;
            q[o..o + e.count].copy_from_slice(&p[e.first..e.first + e.count]);
            qd[o..o + e.count].copy_from_slice(&pd[e.first..e.first + e.count]);
            gamma[o..o + e.count].iter_mut().for_each(|g| *g = 0.0);
        }
        (q, qd, gamma)
    }

    /// Body coordinates q, velocities q_dot = B p_dot and gamma_B = B_dot p_dot at (p, p_dot),
    /// all of length `n` (the model's coordinate count).
    pub fn state(&self, n: usize, p: &[f64], pd: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        self.state_with(n, p, pd, &vec![0.0; p.len()])
    }

    /// The velocity influence coefficients B = dq/dp (n x coordinate_count) at p.
    pub fn influence(&self, n: usize, p: &[f64]) -> Mat<f64> {
        let all: Vec<usize> = (0..self.coordinate_count).collect();
        self.influence_columns(n, p, &all)
    }

    /// The columns `columns` of B at p. A joint coordinate's column takes one pass of the
    /// kinematics; the elastic coordinates act through the six deformation components of the
    /// joint markers on their body (one pass each), then through the markers' shape matrices:
    /// the identity on the body's own elastic coordinates, and dq_r/d(u, theta) S on the
    /// reference coordinates of the bodies beyond (the matrix H_pf of seed eq. 33).
    pub(crate) fn influence_columns(&self, n: usize, p: &[f64], columns: &[usize]) -> Mat<f64> {
        let mut b = Mat::zeros(n, columns.len());
        let njc = self.joint_coordinate_count;
        let joint_columns: Vec<usize> = columns.iter().copied().filter(|&k| k < njc).collect();
        let joints = self.joint_columns(n, p, &joint_columns);
        let mut column_of = vec![usize::MAX; self.coordinate_count];
        for (col, &k) in columns.iter().enumerate() {
            column_of[k] = col;
        }
        for (a, &k) in joint_columns.iter().enumerate() {
            for i in 0..n {
                b[(i, column_of[k])] = joints[(i, a)];
            }
        }
        for e in &self.elastic {
            for k in 0..e.count {
                let col = column_of[e.first + k];
                if col != usize::MAX {
                    b[(self.offsets[e.body] + 7 + k, col)] = 1.0;
                }
            }
        }
        // Elastic columns through each deformed joint marker: D_m S_m.
        for ((body, shape), d) in self.deformed_markers().into_iter().zip(self.marker_derivatives(n, p)) {
            let block = self.elastic.iter().find(|e| e.body == body).expect("a deformable body");
            for c in 0..6 {
                let s = if c < 3 { &shape.translation } else { &shape.rotation };
                for (j, &idx) in shape.indices.iter().enumerate() {
                    let (col, w) = (column_of[block.first + idx], s.get(c % 3, j));
                    if col == usize::MAX || w == 0.0 {
                        continue;
                    }
                    for i in 0..n {
                        b[(i, col)] += w * d[(i, c)];
                    }
                }
            }
        }
        b
    }

    /// dq/dp_k (n rows) for the joint coordinates `columns` at p: one pass each over the
    /// subtree the coordinate's joint moves.
    pub(crate) fn joint_columns(&self, n: usize, p: &[f64], columns: &[usize]) -> Mat<f64> {
        let mut b = Mat::zeros(n, columns.len());
        let mut ph: Vec<HyperDual> = p.iter().map(|&x| HyperDual::constant(x)).collect();
        let deformation = self.deformations(&ph);
        let base = self.poses(&ph, &deformation);
        for (col, &k) in columns.iter().enumerate() {
            ph[k] = HyperDual::curve(p[k], 1.0, 0.0);
            let (poses, moved) = self.poses_beyond(&base, self.joint_of_coordinate(k), &ph, &deformation);
            ph[k] = HyperDual::constant(p[k]);
            self.influence_column(&poses, &moved, &mut b, col);
        }
        b
    }

    /// For each deformed joint marker (in the order of [`Tree::deformed_markers`]), the
    /// derivatives of q (n rows) with respect to its deformation (u - u0, theta) in the body
    /// frame (6 columns): one pass each.
    pub(crate) fn marker_derivatives(&self, n: usize, p: &[f64]) -> Vec<Mat<f64>> {
        let ph: Vec<HyperDual> = p.iter().map(|&x| HyperDual::constant(x)).collect();
        let deformation = self.deformations(&ph);
        let base = self.poses(&ph, &deformation);
        let mut out = Vec::new();
        for (jk, joint) in self.joints.iter().enumerate() {
            for (s, side) in [&joint.parent, &joint.child].into_iter().enumerate() {
                if side.elastic.is_none() {
                    continue;
                }
                let mut d = Mat::zeros(n, 6);
                let mut def = deformation.clone();
                for c in 0..6 {
                    let x = &mut def[jk][s][c / 3][c % 3];
                    *x = HyperDual::curve(x.v, 1.0, 0.0);
                    let (poses, moved) = self.poses_beyond(&base, jk, &ph, &def);
                    let x = &mut def[jk][s][c / 3][c % 3];
                    *x = HyperDual::constant(x.v);
                    self.influence_column(&poses, &moved, &mut d, c);
                }
                out.push(d);
            }
        }
        out
    }
}
