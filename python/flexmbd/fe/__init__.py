"""The preprocessor of deformable bodies (seed section 3): meshes, materials, element matrices,
invariants of motion, reference conditions, modal reduction, and body files.

    from flexmbd.fe import Material, body_from_mesh, save_body, shapes

See ``docs/preprocessor.md``."""

from . import shapes
from .body import FlexibleBodyData, Invariants, ReferenceConditions
from .body_file import load_body, save_body
from .mesh_io import Mesh, read_abaqus_matrix, read_mesh, validate_mesh
from .preprocess import (
    Material,
    Section,
    ShellSection,
    assemble,
    body_from_matrices,
    body_from_mesh,
    build_body,
    straight_beam,
)
from .sid import read_sid, write_sid
from .stress import recover_stresses, shell_stresses, von_mises

__all__ = [
    "FlexibleBodyData",
    "Invariants",
    "Material",
    "Mesh",
    "ReferenceConditions",
    "Section",
    "ShellSection",
    "assemble",
    "body_from_matrices",
    "body_from_mesh",
    "build_body",
    "load_body",
    "read_abaqus_matrix",
    "read_mesh",
    "read_sid",
    "recover_stresses",
    "save_body",
    "shapes",
    "shell_stresses",
    "straight_beam",
    "validate_mesh",
    "von_mises",
    "write_sid",
]
