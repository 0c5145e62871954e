"""The preprocessor of deformable bodies (seed section 3): meshes, materials, element matrices,
invariants of motion, reference conditions, modal reduction, and body files.

    from flexmbd.fe import Material, body_from_mesh, save_body, shapes

See ``docs/preprocessor.md``.

The submodules are imported on first access (PEP 562): ``flexmbd.fe.body`` does not load
meshio or h5py."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_attributes

if TYPE_CHECKING:
    from . import shapes
    from .body import FlexibleBodyData, Invariants, ReferenceConditions
    from .body_file import load_body, save_body
    from .mesh_io import Mesh, orient_shells, read_abaqus_matrix, read_mesh, validate_mesh
    from .nastran import read_nastran
    from .op2 import Op2Results, body_from_nastran, read_op2
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
    from .stress import nodal_von_mises, recover_stresses, shell_stresses, von_mises

#: Public name -> the submodule that defines it ("" for a submodule itself).
_ORIGIN: dict[str, str] = {
    "shapes": "",
    "FlexibleBodyData": "body",
    "Invariants": "body",
    "ReferenceConditions": "body",
    "load_body": "body_file",
    "save_body": "body_file",
    "Mesh": "mesh_io",
    "orient_shells": "mesh_io",
    "read_abaqus_matrix": "mesh_io",
    "read_mesh": "mesh_io",
    "validate_mesh": "mesh_io",
    "read_nastran": "nastran",
    "Op2Results": "op2",
    "body_from_nastran": "op2",
    "read_op2": "op2",
    "Material": "preprocess",
    "Section": "preprocess",
    "ShellSection": "preprocess",
    "assemble": "preprocess",
    "body_from_matrices": "preprocess",
    "body_from_mesh": "preprocess",
    "build_body": "preprocess",
    "straight_beam": "preprocess",
    "read_sid": "sid",
    "write_sid": "sid",
    "recover_stresses": "stress",
    "shell_stresses": "stress",
    "nodal_von_mises": "stress",
    "von_mises": "stress",
}


__getattr__, __dir__ = lazy_attributes(__name__, _ORIGIN, globals())


__all__ = [
    "FlexibleBodyData",
    "Invariants",
    "Material",
    "Mesh",
    "Op2Results",
    "ReferenceConditions",
    "Section",
    "ShellSection",
    "assemble",
    "body_from_matrices",
    "body_from_mesh",
    "body_from_nastran",
    "build_body",
    "load_body",
    "nodal_von_mises",
    "orient_shells",
    "read_abaqus_matrix",
    "read_mesh",
    "read_nastran",
    "read_op2",
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
