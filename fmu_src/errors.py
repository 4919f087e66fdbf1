"""The featherstar error tree.

FeatherstarError
├── ModelError      a model or its parameters are not physical or not well posed (fmu_src)
├── BuildError      code generation, compilation or packaging of an FMU failed (fmu_src)
├── SceneError      a scene is malformed: unknown block, dangling input, loop... (cosim)
├── StepError       a simulation step failed: NaN, blow-up, solver failure (cosim)
├── OptimizerError  bad search space, bounds or log (optimizer)
└── HILError        hardware fault: timeout, lost link, stale or out-of-range data (hil)

The root lives here because fmu_src is the package every other one imports.
"""


class FeatherstarError(Exception):
    """Root of every error featherstar raises on purpose."""


class ModelError(FeatherstarError):
    """A model option or parameter is outside its physical range."""


class BuildError(FeatherstarError):
    """Generating, compiling or packaging an FMU failed."""
