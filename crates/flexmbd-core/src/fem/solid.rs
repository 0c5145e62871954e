//! Solid elements: 4-node and 10-node tetrahedra, 8-node hexahedra (to be written).
