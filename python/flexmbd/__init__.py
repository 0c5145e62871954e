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

import importlib
import logging
import sys
import types
from typing import TYPE_CHECKING, Any

# _boundary wraps the core's methods as it is imported (PyO3's conversion errors become
# ArgumentTypeError naming the parameter) before any other module uses the core: 7 ms, no
# numpy.
from . import _boundary, errors  # noqa: F401
from ._lazy import lazy_attributes
from .errors import (
    ArgumentTypeError,
    CallbackError,
    ConflictingConstraintsError,
    EquilibriumError,
    FlexmbdError,
    FreeMotionError,
    FrozenBodyError,
    InertiaWarning,
    InitialConditionsError,
    InitialCorrectionWarning,
    InvalidModelError,
    InvalidParameterError,
    MeshQualityWarning,
    MissingFileError,
    ModeCountWarning,
    ModelError,
    ModelFileError,
    NewtonDivergedError,
    NonFiniteError,
    NotAResultsFileError,
    ResonanceWarning,
    ResultsFileError,
    SimulationError,
    SimulationInterrupted,
    SingularMatrixError,
    StepSizeTooSmallError,
    StepSizeWarning,
    StudyError,
    UnknownItemError,
)

if TYPE_CHECKING:
    from . import examples
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
    from ._core import (
        BodyId,
        ForceId,
        JointId,
        MarkerId,
        Model,
        SensorId,
        __version__,
    )
    from .analysis import (
        LinearizedSystem,
        equilibrium,
        linearize,
        linearize_at_rest,
        steady_rotation,
    )
    from .campbell import CampbellDiagram, campbell, plot_campbell
    from .dispersion import DispersionBranch, dispersion
    from .floquet import FloquetAnalysis, floquet
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
    from .viewer import view
    from .waves import AxialPulse, axial_pulse

#: Public name -> the submodule that defines it. Importing ``flexmbd`` loads none of them (nor
#: numpy, scipy, h5py, ...): each is imported on first access (PEP 562), so a script or the
#: command line pays only for what it uses.
_ORIGIN: dict[str, str] = {
    "Constant": "_boundary",
    "ExplicitSolver": "_boundary",
    "GeneralizedAlpha": "_boundary",
    "Harmonic": "_boundary",
    "Polynomial": "_boundary",
    "Spline": "_boundary",
    "Step": "_boundary",
    "Trapezoidal": "_boundary",
    "UserFunction": "_boundary",
    "BodyId": "_core",
    "ForceId": "_core",
    "JointId": "_core",
    "MarkerId": "_core",
    "Model": "_core",
    "SensorId": "_core",
    "__version__": "_core",
    "LinearizedSystem": "analysis",
    "equilibrium": "analysis",
    "linearize": "analysis",
    "linearize_at_rest": "analysis",
    "steady_rotation": "analysis",
    "CampbellDiagram": "campbell",
    "campbell": "campbell",
    "plot_campbell": "campbell",
    "FloquetAnalysis": "floquet",
    "floquet": "floquet",
    "DispersionBranch": "dispersion",
    "dispersion": "dispersion",
    "InverseDynamics": "inverse_dynamics",
    "inverse_dynamics": "inverse_dynamics",
    "Result": "result",
    "read_results": "results_file",
    "euler_parameters_to_matrix": "rotation",
    "rotation": "rotation",
    "simulate": "simulation",
    "EquilibriumState": "state",
    "State": "state",
    "BodyPosition": "state_space",
    "ElasticCoordinate": "state_space",
    "NodeDisplacement": "state_space",
    "PointLoad": "state_space",
    "StateSpace": "state_space",
    "Study": "study",
    "load_study": "study",
    "System": "system",
    "view": "viewer",
    "AxialPulse": "waves",
    "axial_pulse": "waves",
    "examples": "",
}

#: Names that are both a submodule and the public function it defines (``fm.rotation(...)``,
#: ``fm.campbell(...)``): the package attribute is always the function, also after the
#: submodule is imported (the import system would otherwise set the attribute to the module).
_FUNCTION_MODULES = frozenset(("campbell", "dispersion", "floquet", "inverse_dynamics", "rotation"))


__getattr__, __dir__ = lazy_attributes(__name__, _ORIGIN, globals())


class _Package(types.ModuleType):
    """The package's module type: keeps `_FUNCTION_MODULES` bound to their functions."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _FUNCTION_MODULES and isinstance(value, types.ModuleType):
            # The import system binds a newly imported submodule on its package.
            value = getattr(value, name)
        super().__setattr__(name, value)

    def __reduce__(self) -> tuple[Any, tuple[str]]:
        # Pickled by name, as cloudpickle pickles plain modules: a function of a script that
        # refers to `fm` (a study's build function, a callback sent to Dask's workers) takes
        # the package along by reference. Without it, "cannot pickle '_Package' object".
        return importlib.import_module, (self.__name__,)


sys.modules[__name__].__class__ = _Package

# The library logs under "flexmbd" and leaves the handlers to its user (a script, the CLI).
logging.getLogger("flexmbd").addHandler(logging.NullHandler())

__all__ = [
    "ArgumentTypeError",
    "BodyId",
    "EquilibriumState",
    "LinearizedSystem",
    "CallbackError",
    "ConflictingConstraintsError",
    "Constant",
    "EquilibriumError",
    "ExplicitSolver",
    "FlexmbdError",
    "ForceId",
    "FreeMotionError",
    "FrozenBodyError",
    "GeneralizedAlpha",
    "Harmonic",
    "InitialConditionsError",
    "InertiaWarning",
    "InitialCorrectionWarning",
    "InvalidModelError",
    "InverseDynamics",
    "InvalidParameterError",
    "MeshQualityWarning",
    "ModeCountWarning",
    "ResonanceWarning",
    "NotAResultsFileError",
    "JointId",
    "MarkerId",
    "Model",
    "ModelError",
    "ModelFileError",
    "NewtonDivergedError",
    "NonFiniteError",
    "Polynomial",
    "Result",
    "MissingFileError",
    "ResultsFileError",
    "SensorId",
    "SimulationError",
    "SimulationInterrupted",
    "SingularMatrixError",
    "Spline",
    "State",
    "Step",
    "StepSizeTooSmallError",
    "StepSizeWarning",
    "StudyError",
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
    "linearize_at_rest",
    "read_results",
    "rotation",
    "simulate",
    "steady_rotation",
    "load_study",
    "CampbellDiagram",
    "campbell",
    "plot_campbell",
    "FloquetAnalysis",
    "floquet",
    "BodyPosition",
    "ElasticCoordinate",
    "NodeDisplacement",
    "PointLoad",
    "StateSpace",
    "DispersionBranch",
    "dispersion",
    "AxialPulse",
    "axial_pulse",
    "view",
]
