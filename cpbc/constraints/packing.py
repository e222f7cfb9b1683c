"""A constraint's share of its set's barrier kernel: :class:`Packed` and the stacked
:class:`PackedSet`, defined with the plan they fill in cpbc.kernels.tables (each kind's
``pack_*`` beside its kernel builds its ``Packed``); named here for the constraint layer."""

from __future__ import annotations

from cpbc.kernels.tables import Ints, Packed, PackedSet

__all__ = ["Ints", "Packed", "PackedSet"]
