"""Type stubs of the Rust extension module ``flexmbd._core`` (docstrings live in the Rust
sources and are shown by ``help()`` at run time)."""

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__version__: str

class BodyId:
    index: int
    _system: int
    def __init__(self, index: int, _system: int = 0) -> None: ...
    def __int__(self) -> int: ...

class MarkerId:
    index: int
    _system: int
    def __init__(self, index: int, _system: int = 0) -> None: ...
    def __int__(self) -> int: ...

class JointId:
    index: int
    _system: int
    def __init__(self, index: int, _system: int = 0) -> None: ...
    def __int__(self) -> int: ...

class ForceId:
    index: int
    _system: int
    def __init__(self, index: int, _system: int = 0) -> None: ...
    def __int__(self) -> int: ...

class SensorId:
    index: int
    _system: int
    def __init__(self, index: int, _system: int = 0) -> None: ...
    def __int__(self) -> int: ...

class Constant:
    value: float
    def __init__(self, value: float) -> None: ...
    def __call__(self, t: float) -> float: ...
    def derivatives(self, t: float) -> tuple[float, float, float]: ...

class Polynomial:
    coefficients: list[float]
    def __init__(self, coefficients: Sequence[float]) -> None: ...
    def __call__(self, t: float) -> float: ...
    def derivatives(self, t: float) -> tuple[float, float, float]: ...

class Harmonic:
    amplitude: float
    frequency: float
    phase: float
    offset: float
    def __init__(
        self, amplitude: float, frequency: float, phase: float = 0.0, offset: float = 0.0
    ) -> None: ...
    def __call__(self, t: float) -> float: ...
    def derivatives(self, t: float) -> tuple[float, float, float]: ...

class Spline:
    times: list[float]
    values: list[float]
    end: str
    slopes: tuple[float, float] | None
    def __init__(
        self,
        times: Sequence[float],
        values: Sequence[float],
        end: str = "natural",
        slopes: tuple[float, float] | None = None,
    ) -> None: ...
    def __call__(self, t: float) -> float: ...
    def derivatives(self, t: float) -> tuple[float, float, float]: ...

class Step:
    start_time: float
    end_time: float
    start_value: float
    end_value: float
    shape: str
    def __init__(
        self,
        start_time: float,
        end_time: float,
        start_value: float,
        end_value: float,
        shape: str = "quintic",
    ) -> None: ...
    def __call__(self, t: float) -> float: ...
    def derivatives(self, t: float) -> tuple[float, float, float]: ...

class Trapezoidal:
    start_time: float
    end_time: float
    start_value: float
    end_value: float
    blend: float
    def __init__(
        self,
        start_time: float,
        end_time: float,
        start_value: float,
        end_value: float,
        blend: float = 0.25,
    ) -> None: ...
    def __call__(self, t: float) -> float: ...
    def derivatives(self, t: float) -> tuple[float, float, float]: ...

class UserFunction:
    function: Callable[[float], Any]
    derivatives: bool
    def __init__(self, function: Callable[[float], Any], derivatives: bool = False) -> None: ...
    def __call__(self, t: float) -> float: ...

Number = float | int
TimeFunctionLike = (
    Number
    | Constant
    | Polynomial
    | Harmonic
    | Spline
    | Step
    | Trapezoidal
    | UserFunction
    | Callable[[float], float]
)

class Model:
    @property
    def _source(self) -> tuple[Any, ...] | None: ...
    @property
    def flexible_bodies(self) -> dict[int, Any]: ...
    @property
    def coordinate_count(self) -> int: ...
    @property
    def constraint_count(self) -> int: ...
    @property
    def initial_coordinates(self) -> NDArray[np.float64]: ...
    @property
    def initial_velocities(self) -> NDArray[np.float64]: ...
    @property
    def matrix_nonzeros(self) -> int: ...
    @property
    def discrete_count(self) -> int: ...
    def describe(self) -> dict[str, Any]: ...
    def discrete_variables(
        self,
        time: float,
        coordinates: NDArray[np.float64],
        velocities: NDArray[np.float64],
        previous: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]: ...
    def evaluate(
        self,
        time: float,
        coordinates: NDArray[np.float64],
        velocities: NDArray[np.float64],
        accelerations: NDArray[np.float64],
        multipliers: NDArray[np.float64],
        *,
        mass: float = 0.0,
        velocity: float = 0.0,
        position: float = 0.0,
        discrete: NDArray[np.float64] | None = None,
    ) -> dict[str, Any]: ...

class System:
    def __init__(self, gravity: ArrayLike | None = None) -> None: ...
    @property
    def ground(self) -> BodyId: ...
    @property
    def gravity(self) -> tuple[float, float, float]: ...
    @gravity.setter
    def gravity(self, value: ArrayLike) -> None: ...
    def add_rigid_body(
        self,
        mass: float,
        inertia: ArrayLike,
        *,
        center_of_mass: ArrayLike | None = None,
        position: ArrayLike | None = None,
        orientation: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
        angular_velocity: ArrayLike | None = None,
        name: str | None = None,
    ) -> BodyId: ...
    def add_point_mass(
        self,
        mass: float,
        *,
        position: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
        name: str | None = None,
    ) -> BodyId: ...
    def add_marker(
        self,
        body: BodyId,
        *,
        position: ArrayLike | None = None,
        orientation: ArrayLike | None = None,
        name: str | None = None,
    ) -> MarkerId: ...
    def _add_flexible_body(
        self,
        *,
        mass: float,
        first_moment: ArrayLike,
        second_moment: ArrayLike,
        i1: NDArray[np.float64],
        ibar: NDArray[np.float64],
        i_kl: Sequence[tuple[Any, Any, Any, int]],
        stiffness: tuple[Any, Any, Any, int],
        damping: tuple[Any, Any, Any, int],
        position: ArrayLike | None = None,
        orientation: ArrayLike | None = None,
        velocity: ArrayLike | None = None,
        angular_velocity: ArrayLike | None = None,
        elastic_coordinates: NDArray[np.float64] | None = None,
        elastic_velocities: NDArray[np.float64] | None = None,
        stiffening: Sequence[tuple[Any, Any, float, float]] | None = None,
        corotational: Sequence[tuple[Any, Any, float, Any]] | None = None,
        dof_nodes: NDArray[np.int64] | None = None,
        node_positions: NDArray[np.float64] | None = None,
        condense: bool | None = None,
        scalar_mass: tuple[tuple[Any, Any, Any, int], NDArray[np.int64]] | None = None,
        attached: Sequence[tuple[Any, Any, Any, Any, Any]] | None = None,
        name: str | None = None,
    ) -> BodyId: ...
    def _add_flexible_marker(
        self,
        body: BodyId,
        *,
        position: ArrayLike,
        indices: NDArray[np.int64],
        translation: NDArray[np.float64],
        rotation: NDArray[np.float64],
        orientation: ArrayLike | None = None,
        name: str | None = None,
    ) -> MarkerId: ...
    def add_spherical_joint(
        self, marker1: MarkerId, marker2: MarkerId, *, name: str | None = None
    ) -> JointId: ...
    def add_revolute_joint(
        self, marker1: MarkerId, marker2: MarkerId, *, name: str | None = None
    ) -> JointId: ...
    def add_cylindrical_joint(
        self, marker1: MarkerId, marker2: MarkerId, *, name: str | None = None
    ) -> JointId: ...
    def add_prismatic_joint(
        self, marker1: MarkerId, marker2: MarkerId, *, name: str | None = None
    ) -> JointId: ...
    def add_fixed_joint(
        self, marker1: MarkerId, marker2: MarkerId, *, name: str | None = None
    ) -> JointId: ...
    def add_universal_joint(
        self, marker1: MarkerId, marker2: MarkerId, *, name: str | None = None
    ) -> JointId: ...
    def add_planar_joint(
        self, marker1: MarkerId, marker2: MarkerId, *, name: str | None = None
    ) -> JointId: ...
    def add_inline_joint(
        self, marker1: MarkerId, marker2: MarkerId, *, name: str | None = None
    ) -> JointId: ...
    def add_distance_joint(
        self,
        marker1: MarkerId,
        marker2: MarkerId,
        distance: float | None = None,
        *,
        name: str | None = None,
    ) -> JointId: ...
    def add_angle_driver(
        self,
        marker1: MarkerId,
        marker2: MarkerId,
        angle: TimeFunctionLike,
        *,
        name: str | None = None,
    ) -> JointId: ...
    def add_translation_driver(
        self,
        marker1: MarkerId,
        marker2: MarkerId,
        displacement: TimeFunctionLike,
        *,
        name: str | None = None,
    ) -> JointId: ...
    def add_point_force(
        self,
        marker: MarkerId,
        force: Sequence[TimeFunctionLike],
        *,
        frame: str = "global",
        name: str | None = None,
    ) -> ForceId: ...
    def add_torque(
        self,
        marker: MarkerId,
        torque: Sequence[TimeFunctionLike],
        *,
        frame: str = "global",
        name: str | None = None,
    ) -> ForceId: ...
    def add_spring_damper(
        self,
        marker1: MarkerId,
        marker2: MarkerId,
        *,
        stiffness: float,
        damping: float = 0.0,
        rest_length: float | None = None,
        preload: float = 0.0,
        name: str | None = None,
    ) -> ForceId: ...
    def add_rotational_spring_damper(
        self,
        marker1: MarkerId,
        marker2: MarkerId,
        *,
        stiffness: float,
        damping: float = 0.0,
        rest_angle: float = 0.0,
        preload: float = 0.0,
        name: str | None = None,
    ) -> ForceId: ...
    def add_joint_actuator(
        self,
        joint: JointId,
        set_point: TimeFunctionLike,
        *,
        proportional_gain: float,
        derivative_gain: float = 0.0,
        feed_forward: TimeFunctionLike | None = None,
        limit: float | None = None,
        coordinate: str | None = None,
        name: str | None = None,
    ) -> ForceId: ...
    def add_callback_force(
        self,
        bodies: Sequence[BodyId],
        function: Callable[[float, NDArray[np.float64], NDArray[np.float64]], ArrayLike],
        *,
        name: str | None = None,
    ) -> ForceId: ...
    def add_sensor(
        self, marker: MarkerId, quantity: str, *, name: str | None = None
    ) -> SensorId: ...
    def compile(
        self, *, flexible_bodies: dict[int, Any] | None = None, source: Any = None
    ) -> Model: ...

class GeneralizedAlpha:
    spectral_radius: float
    newton_tolerance: float
    newton_error_fraction: float
    max_iterations: int
    jacobian: str
    step_control: str
    relative_tolerance: float
    absolute_tolerance: float
    min_step_size: float | None
    max_step_size: float | None
    velocity_projection: str
    linear_solver: str
    initial_tolerance: float
    correct_initial_positions: bool
    correct_initial_velocities: bool
    redundant_constraints: str
    rank_tolerance: float
    def __init__(
        self,
        spectral_radius: float | None = None,
        *,
        newton_tolerance: float | None = None,
        newton_error_fraction: float | None = None,
        max_iterations: int | None = None,
        jacobian: str | None = None,
        step_control: str | None = None,
        relative_tolerance: float | None = None,
        absolute_tolerance: float | None = None,
        min_step_size: float | None = None,
        max_step_size: float | None = None,
        velocity_projection: str | None = None,
        linear_solver: str | None = None,
        initial_tolerance: float | None = None,
        correct_initial_positions: bool | None = None,
        correct_initial_velocities: bool | None = None,
        redundant_constraints: str | None = None,
        rank_tolerance: float | None = None,
    ) -> None: ...
    @staticmethod
    def choices() -> dict[str, list[str]]: ...

class ExplicitSolver:
    method: str
    strategy: str
    formulation: str
    partition: str
    independent: list[int] | None
    baumgarte: tuple[float, float] | None
    relative_tolerance: float
    absolute_tolerance: float
    constraint_tolerance: float
    max_iterations: int
    repartition_ratio: float
    drift_threshold: float
    singular_factor: float
    min_step_size: float | None
    max_step_size: float | None
    initial_tolerance: float
    correct_initial_positions: bool
    correct_initial_velocities: bool
    redundant_constraints: str
    rank_tolerance: float
    cut_joints: list[JointId] | None
    jacobian: str
    def __init__(
        self,
        method: str | None = None,
        strategy: str | None = None,
        *,
        formulation: str | None = None,
        partition: str | None = None,
        independent: Sequence[int] | None = None,
        baumgarte: tuple[float, float] | None = None,
        relative_tolerance: float | None = None,
        absolute_tolerance: float | None = None,
        constraint_tolerance: float | None = None,
        max_iterations: int | None = None,
        repartition_ratio: float | None = None,
        drift_threshold: float | None = None,
        singular_factor: float | None = None,
        min_step_size: float | None = None,
        max_step_size: float | None = None,
        initial_tolerance: float | None = None,
        correct_initial_positions: bool | None = None,
        correct_initial_velocities: bool | None = None,
        redundant_constraints: str | None = None,
        rank_tolerance: float | None = None,
        cut_joints: list[JointId] | None = None,
        jacobian: str | None = None,
    ) -> None: ...
    @staticmethod
    def choices() -> dict[str, list[str]]: ...

def simulate(
    model: Model,
    end_time: float,
    step_size: float,
    *,
    start_time: float = 0.0,
    output_interval: float | None = None,
    solver: GeneralizedAlpha | ExplicitSolver | None = None,
    progress: Callable[[float, float, int], object] | None = None,
    records: Callable[[dict[str, Any]], object] | None = None,
    coordinates: NDArray[np.float64] | None = None,
    velocities: NDArray[np.float64] | None = None,
    discrete: NDArray[np.float64] | None = None,
    recorded: bool = False,
    initial_conditions: str = "correct",
    keep_in_memory: bool = True,
) -> tuple[dict[str, Any], BaseException | None]: ...

class Material:
    def __init__(
        self, young_modulus: float, poisson_ratio: float, density: float, *, name: str | None = None
    ) -> None: ...
    @property
    def young_modulus(self) -> float: ...
    @property
    def poisson_ratio(self) -> float: ...
    @property
    def density(self) -> float: ...
    @property
    def shear_modulus(self) -> float: ...

class Section:
    def __init__(self, area: float, iy: float, iz: float, torsion_constant: float) -> None: ...
    @staticmethod
    def rectangle(b: float, h: float) -> Section: ...
    @staticmethod
    def circle(r: float) -> Section: ...
    @staticmethod
    def tube(outer: float, inner: float) -> Section: ...
    @property
    def area(self) -> float: ...
    @property
    def iy(self) -> float: ...
    @property
    def iz(self) -> float: ...
    @property
    def torsion_constant(self) -> float: ...
    @property
    def shear_factor(self) -> float: ...
    def with_shear_factor(self, kappa: float) -> Section: ...
    @property
    def rotary_inertia(self) -> bool: ...
    def without_rotary_inertia(self) -> Section: ...

class ShellSection:
    def __init__(self, thickness: float, *, shear_factor: float = ...) -> None: ...
    @property
    def thickness(self) -> float: ...
    @property
    def shear_factor(self) -> float: ...

class FeMesh:
    def __init__(
        self,
        nodes: NDArray[np.float64],
        node_ids: NDArray[np.int64],
        elements: dict[str, tuple[NDArray[np.int64], NDArray[np.int64]]],
        material: Material,
        section: Section | None = None,
        orientation: Sequence[float] | None = None,
        shear: bool = False,
        shell: ShellSection | None = None,
    ) -> None: ...
    @property
    def dofs_per_node(self) -> int: ...

def assemble_body(mesh: FeMesh, lumped: bool = False) -> dict[str, Any]: ...
def recover_stresses(
    mesh: FeMesh, displacements: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]: ...
def body_mass_points(
    mesh: FeMesh, lumped: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[Any, Any, Any, tuple[int, int]]]: ...
def shell_membrane_stiffening(
    nodes: NDArray[np.float64], shell: ShellSection, material: Material
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]: ...
def beam_corotational_terms(
    nodes: NDArray[np.float64],
    section: Section,
    material: Material,
    orientation: list[float] | None = None,
    shear: bool = False,
) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]: ...

class SymmetricFactor:
    def __init__(
        self,
        n: int,
        indptr: NDArray[np.int64],
        indices: NDArray[np.int64],
        data: NDArray[np.float64],
        *,
        dof_nodes: NDArray[np.int64] | None = None,
        positions: NDArray[np.float64] | None = None,
        ordering: NDArray[np.int64] | None = None,
        positive: int | None = None,
        single: bool = False,
        threads: int = 1,
        name: str = "matrix",
    ) -> None: ...
    @property
    def dim(self) -> int: ...
    @property
    def factor_nnz(self) -> int: ...
    @property
    def factor_bytes(self) -> int: ...
    def solve(self, b: NDArray[np.float64], refine: int = 0) -> NDArray[np.float64]: ...
    def multiply(self, x: NDArray[np.float64]) -> NDArray[np.float64]: ...
