"""A scenario's constrained law as a Gymnasium environment for a learned policy
(``make_env``). Needs gymnasium: ``pip install 'cpbc[gym]'``; the rest of cpbc never
imports it."""

try:
    import gymnasium  # noqa: F401 (present or not: checked here, once)
except ImportError as exc:
    raise ImportError("cpbc.gym needs gymnasium, which is not installed: "
                      "pip install 'cpbc[gym]'") from exc

from cpbc.gym.env import ACTIONS, EnvSettings, ScenarioEnv, make_env

__all__ = ["ACTIONS", "EnvSettings", "ScenarioEnv", "make_env"]
