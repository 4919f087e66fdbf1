"""Bayesian optimization of the feather stroke, morphology sweeps and co-design (paper Sec. II-D).

The optimizer never owns the simulation: `StrokeOptimizer` is ask/tell, and everything it
evaluates is an `Objective` (the FMU master through `SceneObjective`, or any callable returning a
thrust `Trace`). Experiments run on an `Executor`: this process, local processes or a Dask
cluster. Errors are `OptimizerError` (a `FeatherstarError`).
"""
from .acquisition import expected_improvement_plus
from .bayes import Estimate, OptimizationRun, StrokeOptimizer, optimize
from .codesign import codesign
from .errors import OptimizerError
from .evaluation import Evaluation, MeasurementPlan, Validation, evaluate, validate
from .executor import DaskExecutor, Executor, InlineExecutor, ProcessExecutor, make_executor
from .loadcell import LoadCell, Measurement, measure
from .objective import Objective, SceneObjective, Trace, WithOverrides
from .space import SearchSpace, ServoLimits, Variable, stroke_space, symmetric_stroke
from .study import run_study
from .sweep import Controller, Geometry, SweepResult, paper_geometries, run_sweep
from .synthetic import SyntheticFeather

__all__ = [
    "Controller", "DaskExecutor", "Estimate", "Evaluation", "Executor", "InlineExecutor", "ProcessExecutor", "Geometry", "LoadCell", "Measurement", "MeasurementPlan",
    "Objective", "OptimizationRun", "OptimizerError", "SceneObjective", "SearchSpace", "ServoLimits",
    "StrokeOptimizer", "SweepResult", "SyntheticFeather", "Trace", "Validation", "Variable", "WithOverrides",
    "codesign", "evaluate", "expected_improvement_plus", "make_executor", "measure", "optimize", "paper_geometries",
    "run_study", "run_sweep", "stroke_space", "symmetric_stroke", "validate",
]
