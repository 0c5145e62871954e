"""The preprocessor of deformable bodies (seed section 3): meshes, materials, element matrices,
invariants of motion, reference conditions, modal reduction, and body files."""

from .body import FlexibleBodyData

__all__ = ["FlexibleBodyData"]
