"""Controller layer: closed-form laws τ = k(x, ẋ) of Chapters 6–7 and the PD baselines."""

from cpbc.controllers.bpbc import BPBC
from cpbc.controllers.bpbc_ke import BPBCKineticEnergy
from cpbc.controllers.controller import Controller
from cpbc.controllers.cpbc import CPBC
from cpbc.controllers.cpbc_ke import CPBCKineticEnergy
from cpbc.controllers.pd import PD, PDGravity
from cpbc.controllers.recentred import RecentredBarrier
from cpbc.controllers.shaping import Identity, Power, Tanh
from cpbc.controllers.task_damping import TaskDamping, TaskTanhDamping

__all__ = [
    "BPBC",
    "CPBC",
    "PD",
    "BPBCKineticEnergy",
    "CPBCKineticEnergy",
    "Controller",
    "Identity",
    "PDGravity",
    "Power",
    "RecentredBarrier",
    "Tanh",
    "TaskDamping",
    "TaskTanhDamping",
]
