"""flexmbd: flexible multibody dynamics.

Build a :class:`System` of bodies, markers, joints and forces, then :func:`simulate` it::

    import flexmbd as fm
    system = fm.System(gravity=(0, -9.81, 0))
    mass = system.add_point_mass(1.0, position=(1, 0, 0))
    pivot = system.add_marker(system.ground)
    bob = system.add_marker(mass)
    system.add_distance_joint(pivot, bob, 1.0)
    result = fm.simulate(system, end_time=2.0, step_size=1e-3)
    result.position(mass)       # (n, 3) array, time first

Units are SI by convention. See ``docs/`` for the theory and the solver choices.
"""

from __future__ import annotations

import logging

from . import errors, examples
from ._boundary import (
    Constant,
    ExplicitSolver,
    GeneralizedAlpha,
    Harmonic,
    Polynomial,
    Spline,
    Step,
    Trapezoidal,
    UserFunction,
)
from ._core import BodyId, ForceId, JointId, MarkerId, Model, SensorId, __version__
from .analysis import LinearizedSystem, equilibrium, linearize, steady_rotation
from .campbell import CampbellDiagram, campbell, plot_campbell
from .dispersion import DispersionBranch, dispersion
from .errors import (
    ArgumentTypeError,
    CallbackError,
    EquilibriumError,
    FlexmbdError,
    FrozenBodyError,
    InitialConditionsError,
    InitialCorrectionWarning,
    InvalidModelError,
    InvalidParameterError,
    ModelError,
    ModelFileError,
    NewtonDivergedError,
    NonFiniteError,
    ResultsFileError,
    SimulationError,
    SimulationInterrupted,
    SingularMatrixError,
    StepSizeTooSmallError,
    UnknownItemError,
)
from .inverse_dynamics import InverseDynamics, inverse_dynamics
from .result import Result
from .results_file import read_results
from .rotation import euler_parameters_to_matrix, rotation
from .simulation import simulate
from .state import EquilibriumState, State
from .state_space import (
    BodyPosition,
    ElasticCoordinate,
    NodeDisplacement,
    PointLoad,
    StateSpace,
)
from .study import Study, load_study
from .system import System
from .waves import AxialPulse, axial_pulse

# The library logs under "flexmbd" and leaves the handlers to its user (a script, the CLI).
logging.getLogger("flexmbd").addHandler(logging.NullHandler())

__all__ = [
    "ArgumentTypeError",
    "BodyId",
    "EquilibriumState",
    "LinearizedSystem",
    "CallbackError",
    "Constant",
    "EquilibriumError",
    "ExplicitSolver",
    "FlexmbdError",
    "ForceId",
    "FrozenBodyError",
    "GeneralizedAlpha",
    "Harmonic",
    "InitialConditionsError",
    "InitialCorrectionWarning",
    "InvalidModelError",
    "InverseDynamics",
    "InvalidParameterError",
    "JointId",
    "MarkerId",
    "Model",
    "ModelError",
    "ModelFileError",
    "NewtonDivergedError",
    "NonFiniteError",
    "Polynomial",
    "Result",
    "ResultsFileError",
    "SensorId",
    "SimulationError",
    "SimulationInterrupted",
    "SingularMatrixError",
    "Spline",
    "State",
    "Step",
    "StepSizeTooSmallError",
    "Study",
    "System",
    "Trapezoidal",
    "UnknownItemError",
    "UserFunction",
    "__version__",
    "equilibrium",
    "inverse_dynamics",
    "errors",
    "euler_parameters_to_matrix",
    "examples",
    "linearize",
    "read_results",
    "rotation",
    "simulate",
    "steady_rotation",
    "load_study",
    "CampbellDiagram",
    "campbell",
    "plot_campbell",
    "BodyPosition",
    "ElasticCoordinate",
    "NodeDisplacement",
    "PointLoad",
    "StateSpace",
    "DispersionBranch",
    "dispersion",
    "AxialPulse",
    "axial_pulse",
]
