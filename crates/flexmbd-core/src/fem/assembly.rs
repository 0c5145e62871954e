//! Assembly of a deformable body from its elements (seed eqs. 9, 16-17): the nodal stiffness
//! and mass matrices K_ff, M_ff and the invariants of motion, all through the connectivity.
//!
//! Nodal coordinates are node-major with `dofs_per_node` coordinates per node (3 for solids,
//! 6 when beams are present; a solid element uses the first three of its nodes). Sparse
//! matrices share a node-block pattern: the (i, j) block exists when nodes i and j share an
//! element. For bodies made of solids only, whose shape matrices are S = [N_1 I, N_2 I, ...],
//! I_kl = M_s (x) e_k e_l^T with the scalar mass matrix M_s = sum rho N_i N_j: M_s is stored
//! instead of nine matrices.

use crate::error::{FlexmbdError, Result};
use crate::linalg::csc::Csc;
use crate::math::dense::DenseMatrix;
use crate::math::{Mat3, Vec3};

use crate::fem::beam::Beam;
use crate::fem::element::{ElementKernel, MassPoint};
use crate::fem::material::Material;
use crate::fem::shell::{ShellKernel, ShellQuad4, ShellTri3};
use crate::fem::solid::{
    Hex20, Hex20Reduced, Hex27, Hex8, Hex8Incompatible, Pyramid13, Pyramid14, Pyramid5, Tet10, Tet4, Wedge15,
    Wedge18, Wedge6,
};

/// The element types a body can be made of.
#[derive(Clone, Debug, PartialEq)]
pub enum ElementType {
    /// Two-node beam (Euler-Bernoulli or Timoshenko).
    Beam(Beam),
    /// Four-node tetrahedron.
    Tet4,
    /// Ten-node tetrahedron (Gmsh node order).
    Tet10,
    /// Eight-node hexahedron.
    Hex8,
    /// Eight-node hexahedron with incompatible modes (Abaqus' C3D8I).
    Hex8Incompatible,
    /// Twenty-node hexahedron (VTK node order).
    Hex20,
    /// Twenty-node hexahedron with reduced integration (Abaqus' C3D20R).
    Hex20Reduced,
    /// Twenty-seven-node (triquadratic) hexahedron (VTK node order).
    Hex27,
    /// Six-node wedge (triangular prism).
    Wedge6,
    /// Fifteen-node wedge (Abaqus C3D15 node order).
    Wedge15,
    /// Eighteen-node (Lagrange) wedge (the node order of `fem::solid`).
    Wedge18,
    /// Five-node pyramid (Gmsh node order).
    Pyramid5,
    /// Thirteen-node pyramid (VTK node order).
    Pyramid13,
    /// Fourteen-node pyramid (VTK's 13-node order, then the base's centre).
    Pyramid14,
    /// Four-node flat shell (MITC4).
    Quad4(ShellQuad4),
    /// Three-node flat shell (DKT).
    Tri3(ShellTri3),
}

impl ElementType {
    fn kernel(&self) -> &dyn ElementKernel {
        match self {
            ElementType::Beam(b) => b,
            ElementType::Tet4 => &Tet4,
            ElementType::Tet10 => &Tet10,
            ElementType::Hex8 => &Hex8,
            ElementType::Hex8Incompatible => &Hex8Incompatible,
            ElementType::Hex20 => &Hex20,
            ElementType::Hex20Reduced => &Hex20Reduced,
            ElementType::Hex27 => &Hex27,
            ElementType::Wedge6 => &Wedge6,
            ElementType::Wedge15 => &Wedge15,
            ElementType::Wedge18 => &Wedge18,
            ElementType::Pyramid5 => &Pyramid5,
            ElementType::Pyramid13 => &Pyramid13,
            ElementType::Pyramid14 => &Pyramid14,
            ElementType::Quad4(s) => s,
            ElementType::Tri3(s) => s,
        }
    }

    /// The shell kernel of shell elements.
    fn shell(&self) -> Option<&dyn ShellKernel> {
        match self {
            ElementType::Quad4(s) => Some(s),
            ElementType::Tri3(s) => Some(s),
            _ => None,
        }
    }

    /// True for solid elements (translations only in their shape matrices).
    pub fn is_solid(&self) -> bool {
        matches!(
            self,
            ElementType::Tet4
                | ElementType::Tet10
                | ElementType::Hex8
                | ElementType::Hex8Incompatible
                | ElementType::Hex20
                | ElementType::Hex20Reduced
                | ElementType::Hex27
                | ElementType::Wedge6
                | ElementType::Wedge15
                | ElementType::Wedge18
                | ElementType::Pyramid5
                | ElementType::Pyramid13
                | ElementType::Pyramid14
        )
    }
}

/// An element of a body.
#[derive(Clone, Debug, PartialEq)]
pub struct Element {
    /// Id in the source mesh (for messages).
    pub id: i64,
    /// Type and properties.
    pub kind: ElementType,
    /// Indices of its nodes.
    pub nodes: Vec<usize>,
}

/// A finite-element description of a deformable body.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Undeformed node positions in the body frame (m).
    pub nodes: Vec<Vec3>,
    /// Node ids in the source mesh (for messages).
    pub node_ids: Vec<i64>,
    /// Elements.
    pub elements: Vec<Element>,
    /// Material of all elements.
    pub material: Material,
}

/// Invariants of motion in nodal coordinates (`DESIGN.md`, seed eqs. 16-17).
#[derive(Clone, Debug, PartialEq)]
pub struct NodalInvariants {
    /// m = int rho dV (kg).
    pub mass: f64,
    /// s0 = int rho u0 dV (kg m).
    pub first_moment: Vec3,
    /// J0_kl = int rho u0_k u0_l dV (kg m^2).
    pub second_moment: Mat3,
    /// I1 = int rho S dV, 3 x n row-major.
    pub i1: Vec<f64>,
    /// Ibar_kl = int rho u0_k S_l dV, index [(3 k + l) n + dof].
    pub ibar: Vec<f64>,
    /// I_kl = int rho S_k^T S_l dV.
    pub i_kl: Ikl,
}

/// Storage of the nine I_kl.
#[derive(Clone, Debug, PartialEq)]
pub enum Ikl {
    /// Solids only: I_kl = M_s (x) e_k e_l^T with the scalar nodal mass matrix M_s.
    Scalar(Csc),
    /// General (beams): the nine matrices, index 3 k + l.
    Blocks(Vec<Csc>),
}

/// The assembled body.
#[derive(Clone, Debug, PartialEq)]
pub struct AssembledBody {
    /// Coordinates per node.
    pub dofs_per_node: usize,
    /// K_ff (nodal).
    pub stiffness: Csc,
    /// M_ff = sum_k I_kk (nodal), consistent or lumped as requested.
    pub mass: Csc,
    /// Invariants of the same mass distribution.
    pub invariants: NodalInvariants,
}

/// Node adjacency (sorted, including each node itself) and the block CSC pattern it defines.
struct BlockPattern {
    adjacency: Vec<Vec<usize>>,
    d: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
}

impl BlockPattern {
    fn new(n_nodes: usize, elements: &[Element], d: usize) -> Self {
        let mut adjacency: Vec<Vec<usize>> = vec![Vec::new(); n_nodes];
        for e in elements {
            for &i in &e.nodes {
                adjacency[i].extend_from_slice(&e.nodes);
            }
        }
        for a in adjacency.iter_mut() {
            a.sort_unstable();
            a.dedup();
        }
        let mut col_ptr = Vec::with_capacity(n_nodes * d + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for adj in &adjacency {
            for _ in 0..d {
                for &i in adj {
                    for a in 0..d {
                        row_idx.push(d * i + a);
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        BlockPattern { adjacency, d, col_ptr, row_idx }
    }

    /// Value index of entry (node i comp a, node j comp b).
    fn index(&self, i: usize, a: usize, j: usize, b: usize) -> usize {
        let pos = self.adjacency[j].binary_search(&i).expect("node pair in the pattern");
        self.col_ptr[self.d * j + b] + pos * self.d + a
    }

    fn matrix(&self, values: Vec<f64>) -> Csc {
        let n = self.adjacency.len() * self.d;
        Csc { nrows: n, ncols: n, col_ptr: self.col_ptr.clone(), row_idx: self.row_idx.clone(), values }
    }
}

fn element_error(e: &Element, err: crate::fem::element::ElementError) -> FlexmbdError {
    FlexmbdError::InvalidModel { item: format!("element {}", e.id), message: err.to_string() }
}

/// Stresses recovered from a displacement field of a body (see [`Mesh::recover_stresses`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecoveredStresses {
    /// Per node: the stress of the solid elements around it, averaged (Voigt order
    /// xx, yy, zz, yz, xz, xy; body axes; Pa); zeros at nodes of beams only.
    pub nodal: Vec<[f64; 6]>,
    /// Per beam element (in mesh order): the section resultants [N, V_y, V_z, T, M_y, M_z] at
    /// its two ends, element axes (N, N m).
    pub beams: Vec<[[f64; 6]; 2]>,
    /// Per node: the stresses at the top (z = t/2 along the element normal), middle and bottom
    /// surfaces of the shell elements around it, averaged (Voigt order, body axes, Pa); zeros
    /// at nodes without shells. The middle values are also in `nodal`.
    pub shells: Vec<[[f64; 6]; 3]>,
}

impl Mesh {
    /// Recovers stresses from nodal displacements `u` (node-major, `dofs_per_node` per node,
    /// body axes): solid and shell stresses evaluated at the element nodes and averaged over
    /// the elements that share a node (shells: at three surfaces, the middle one in `nodal`),
    /// and the section resultants at the ends of every beam.
    pub fn recover_stresses(&self, u: &[f64]) -> Result<RecoveredStresses> {
        let d = self.dofs_per_node();
        let n = self.nodes.len();
        if u.len() != n * d {
            return Err(FlexmbdError::InvalidParameter {
                item: "stress recovery".to_string(),
                message: format!("{} displacements given, the mesh has {}", u.len(), n * d),
            });
        }
        let mut nodal = vec![[0.0; 6]; n];
        let mut count = vec![0usize; n];
        let mut shells = vec![[[0.0; 6]; 3]; n];
        let mut shell_count = vec![0usize; n];
        let mut levels = Vec::new();
        let mut beams = Vec::new();
        let mut x = Vec::new();
        let mut ue = Vec::new();
        let mut out = Vec::new();
        for e in &self.elements {
            let kernel = e.kind.kernel();
            let per = kernel.dofs_per_node();
            x.clear();
            ue.clear();
            for &a in &e.nodes {
                x.push(self.nodes[a]);
                ue.extend_from_slice(&u[d * a..d * a + per]);
            }
            out.clear();
            out.resize(e.nodes.len(), [0.0; 6]);
            kernel.nodal_stresses(&self.material, &x, &ue, &mut out).map_err(|err| element_error(e, err))?;
            if let Some(shell) = e.kind.shell() {
                levels.clear();
                levels.resize(e.nodes.len(), [[0.0; 6]; 3]);
                shell
                    .surface_stresses(&self.material, &x, &ue, &mut levels)
                    .map_err(|err| element_error(e, err))?;
                for (k, &a) in e.nodes.iter().enumerate() {
                    for (level, values) in levels[k].iter().enumerate() {
                        for r in 0..6 {
                            shells[a][level][r] += values[r];
                        }
                    }
                    shell_count[a] += 1;
                }
            }
            if e.kind.is_solid() || e.kind.shell().is_some() {
                for (k, &a) in e.nodes.iter().enumerate() {
                    for r in 0..6 {
                        nodal[a][r] += out[k][r];
                    }
                    count[a] += 1;
                }
            } else {
                beams.push([out[0], out[1]]);
            }
        }
        for (s, &c) in nodal.iter_mut().zip(&count) {
            if c > 0 {
                s.iter_mut().for_each(|v| *v /= c as f64);
            }
        }
        for (s, &c) in shells.iter_mut().zip(&shell_count) {
            if c > 0 {
                s.iter_mut().flatten().for_each(|v| *v /= c as f64);
            }
        }
        Ok(RecoveredStresses { nodal, beams, shells })
    }

    /// Coordinates per node of the body: 6 when any beam or shell is present, else 3.
    pub fn dofs_per_node(&self) -> usize {
        if self.elements.iter().any(|e| !e.kind.is_solid()) {
            6
        } else {
            3
        }
    }

    /// Checks node references, node counts per element, repeated nodes in an element, and
    /// that every element has a positive volume.
    pub fn validate(&self) -> Result<()> {
        if self.node_ids.len() != self.nodes.len() {
            return Err(FlexmbdError::InvalidModel {
                item: "mesh".to_string(),
                message: format!("{} node ids for {} nodes", self.node_ids.len(), self.nodes.len()),
            });
        }
        if let Some(k) = self.nodes.iter().position(|x| !x.is_finite()) {
            return Err(FlexmbdError::InvalidParameter {
                item: format!("node {}", self.node_ids[k]),
                message: "position must be finite".to_string(),
            });
        }
        for e in &self.elements {
            let kernel = e.kind.kernel();
            if e.nodes.len() != kernel.node_count() {
                return Err(FlexmbdError::InvalidModel {
                    item: format!("element {}", e.id),
                    message: format!("expected {} nodes, got {}", kernel.node_count(), e.nodes.len()),
                });
            }
            if let Some(&bad) = e.nodes.iter().find(|&&n| n >= self.nodes.len()) {
                return Err(FlexmbdError::UnknownItem {
                    kind: "node",
                    id: bad,
                    context: format!(" (used by element {})", e.id),
                });
            }
            let mut sorted = e.nodes.clone();
            sorted.sort_unstable();
            if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
                return Err(FlexmbdError::InvalidModel {
                    item: format!("element {}", e.id),
                    message: format!("node {} appears twice", self.node_ids[w[0]]),
                });
            }
            let x: Vec<Vec3> = e.nodes.iter().map(|&n| self.nodes[n]).collect();
            let volume = kernel.volume(&x).map_err(|err| element_error(e, err))?;
            if !(volume > 0.0) {
                return Err(FlexmbdError::InvalidModel {
                    item: format!("element {}", e.id),
                    message: format!("non-positive volume {volume:e}"),
                });
            }
        }
        Ok(())
    }

    /// Global coordinate indices of an element's local coordinates.
    fn element_dofs(&self, e: &Element, d: usize) -> Vec<usize> {
        let per = e.kind.kernel().dofs_per_node();
        e.nodes.iter().flat_map(|&n| (0..per).map(move |c| d * n + c)).collect()
    }

    /// Calls `f(point, dofs)` for every mass point of the body (consistent or lumped), with the
    /// global coordinate indices of the point's shape matrix columns.
    pub fn for_each_mass_point(&self, lumped: bool, mut f: impl FnMut(&MassPoint, &[usize])) -> Result<()> {
        self.validate()?;
        let d = self.dofs_per_node();
        let mut points = Vec::new();
        let mut x = Vec::new();
        for e in &self.elements {
            let dofs = self.element_mass_points(e, d, lumped, &mut x, &mut points)?;
            for p in &points {
                f(p, &dofs);
            }
        }
        Ok(())
    }

    /// Mass points of one element into `points`; returns its global coordinate indices.
    fn element_mass_points(
        &self,
        e: &Element,
        d: usize,
        lumped: bool,
        x: &mut Vec<Vec3>,
        points: &mut Vec<MassPoint>,
    ) -> Result<Vec<usize>> {
        let kernel = e.kind.kernel();
        x.clear();
        x.extend(e.nodes.iter().map(|&i| self.nodes[i]));
        points.clear();
        if lumped {
            kernel.lumped_mass_points(&self.material, x, points)
        } else {
            kernel.mass_points(&self.material, x, points)
        }
        .map_err(|err| element_error(e, err))?;
        Ok(self.element_dofs(e, d))
    }

    /// Assembles K_ff, M_ff and the invariants of the consistent (`lumped = false`) or lumped
    /// mass distribution.
    pub fn assemble(&self, lumped: bool) -> Result<AssembledBody> {
        self.validate()?;
        let d = self.dofs_per_node();
        let n_nodes = self.nodes.len();
        let n = n_nodes * d;
        let pattern = BlockPattern::new(n_nodes, &self.elements, d);
        let nnz = pattern.row_idx.len();
        let mut k_values = vec![0.0; nnz];
        let mut m_values = vec![0.0; nnz];
        let solids_only = d == 3;
        let scalar_pattern =
            if solids_only { Some(BlockPattern::new(n_nodes, &self.elements, 1)) } else { None };
        let mut ms_values = vec![0.0; scalar_pattern.as_ref().map_or(0, |p| p.row_idx.len())];
        let mut ikl_values: Vec<Vec<f64>> = if solids_only { Vec::new() } else { vec![vec![0.0; nnz]; 9] };
        let mut mass = 0.0;
        let mut first = Vec3::ZERO;
        let mut second = Mat3::default();
        let mut i1 = vec![0.0; 3 * n];
        let mut ibar = vec![0.0; 9 * n];

        let mut ke = DenseMatrix::default();
        let mut points: Vec<MassPoint> = Vec::new();
        let mut x: Vec<Vec3> = Vec::new();
        for e in &self.elements {
            let kernel = e.kind.kernel();
            let dofs = self.element_mass_points(e, d, lumped, &mut x, &mut points)?;
            let ne = dofs.len();
            let per = kernel.dofs_per_node();
            // Stiffness.
            kernel.stiffness(&self.material, &x, &mut ke).map_err(|err| element_error(e, err))?;
            for a in 0..ne {
                for b in 0..ne {
                    let (na, ca) = (e.nodes[a / per], a % per);
                    let (nb, cb) = (e.nodes[b / per], b % per);
                    k_values[pattern.index(na, ca, nb, cb)] += ke.get(a, b);
                }
            }
            // Mass points: mass matrix and invariants.
            for p in &points {
                let w = p.weight;
                mass += w;
                first += p.position * w;
                second = second + p.position.outer(&p.position).scale(w);
                for row in 0..3 {
                    for a in 0..ne {
                        let s = p.shape[row * ne + a];
                        if s == 0.0 {
                            continue;
                        }
                        i1[row * n + dofs[a]] += w * s;
                        for k in 0..3 {
                            ibar[(3 * k + row) * n + dofs[a]] += w * p.position[k] * s;
                        }
                    }
                }
                if let Some(sp) = &scalar_pattern {
                    // Solids: N_a from the x row on the x coordinate of each node.
                    for (la, &na) in e.nodes.iter().enumerate() {
                        let sa = p.shape[3 * la];
                        if sa == 0.0 {
                            continue;
                        }
                        for (lb, &nb) in e.nodes.iter().enumerate() {
                            ms_values[sp.index(na, 0, nb, 0)] += w * sa * p.shape[3 * lb];
                        }
                    }
                } else {
                    for a in 0..ne {
                        let (na, ca) = (e.nodes[a / per], a % per);
                        for b in 0..ne {
                            let (nb, cb) = (e.nodes[b / per], b % per);
                            let idx = pattern.index(na, ca, nb, cb);
                            for k in 0..3 {
                                let ska = p.shape[k * ne + a];
                                if ska == 0.0 {
                                    continue;
                                }
                                for l in 0..3 {
                                    ikl_values[3 * k + l][idx] += w * ska * p.shape[l * ne + b];
                                }
                            }
                        }
                    }
                }
            }
        }
        // M_ff = sum_k I_kk.
        let i_kl = match scalar_pattern {
            Some(sp) => {
                for j in 0..n_nodes {
                    for (pos, &i) in sp.adjacency[j].iter().enumerate() {
                        let v = ms_values[sp.col_ptr[j] + pos];
                        for c in 0..3 {
                            m_values[pattern.index(i, c, j, c)] += v;
                        }
                    }
                }
                Ikl::Scalar(sp.matrix(ms_values))
            }
            None => {
                for k in 0..3 {
                    for (mv, v) in m_values.iter_mut().zip(&ikl_values[4 * k]) {
                        *mv += v;
                    }
                }
                Ikl::Blocks(ikl_values.into_iter().map(|v| pattern.matrix(v)).collect())
            }
        };
        Ok(AssembledBody {
            dofs_per_node: d,
            stiffness: pattern.matrix(k_values),
            mass: pattern.matrix(m_values),
            invariants: NodalInvariants { mass, first_moment: first, second_moment: second, i1, ibar, i_kl },
        })
    }
}
