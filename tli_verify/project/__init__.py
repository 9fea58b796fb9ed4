"""The project session: files found, read and settled once (:func:`open_project`), and the
one control-period rule (:func:`control_period`).

Sits below the public API, the commands, the Franka loop, the experiments and the gate; above
campaigns, the runtime and the file formats.
"""

from tli_verify.project.period import control_period, task_period
from tli_verify.project.session import Session, locate, open_project

__all__ = ["Session", "control_period", "locate", "open_project", "task_period"]
