"""Every network kind, declared: importing this module completes :data:`NETWORK_KINDS` (their catalogue).

Each kind is declared by the module that holds its networks, imported here in the order the kinds are
listed (``nets.py``: mlp, conv, lstm; ``delan.py``: delan); a kind declared elsewhere (a test's toy, a
plugin) is appended after them. What a kind is: ``learn/kind_registry.py``.
"""
from __future__ import annotations

from . import nets, delan  # noqa: F401  (they declare the built-in kinds, in this order)
from .kind_registry import (DELAN_PARTS, NET_PARTS, NETWORK_KINDS, SPACE, NetworkKind, build_net, build_parts,
                            clips_gradients, cost_rank, fast_net_front, preset_problems, search_fc)
from .nets import single_net

__all__ = ["DELAN_PARTS", "NETWORK_KINDS", "NET_PARTS", "NetworkKind", "SPACE", "build_net", "build_parts",
           "clips_gradients", "cost_rank", "fast_net_front", "preset_problems", "search_fc", "single_net"]
