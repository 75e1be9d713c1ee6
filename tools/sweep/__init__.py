"""tools/sweep/ - error against render time, the package behind tools/sweep.py (its docstring
says what it renders and writes). One module a job: common, fitmath, scenes, runner, plan,
analysis, main."""

from .analysis import *  # noqa: F401,F403
from .common import *  # noqa: F401,F403
from .fitmath import *  # noqa: F401,F403
from .main import main  # noqa: F401
from .plan import *  # noqa: F401,F403
from .runner import *  # noqa: F401,F403
from .scenes import *  # noqa: F401,F403
