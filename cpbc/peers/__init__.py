"""Peers: the approaches users pick today, built on the same constraint objects as the laws so
that they can run beside them (``type: cbf_qp``). Optional: ``pip install 'cpbc[peers]'``."""

from cpbc.peers.cbf_qp import CBFQP, PeerUnavailable

__all__ = ["CBFQP", "PeerUnavailable"]
