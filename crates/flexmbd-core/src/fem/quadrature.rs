//! Quadrature rules on the reference tetrahedron and hexahedron (to be written).
