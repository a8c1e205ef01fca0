"""Every network kind, declared: importing this module completes the kind registry.

The registry and what a kind is live in ``learn/kind_registry.py`` (re-exported here, so
``from hybrid_dyn.learn.kinds import NetworkKind, register, network_kind, ...`` works as before);
each kind is declared by the module that holds its networks:

- ``learn/nets.py``: ``mlp``, ``conv``, ``lstm`` (the seed's families);
- ``learn/delan.py``: ``delan`` (Deep Lagrangian Networks).

They are imported in that order, the order the kinds are listed in (``KINDS``, the errors). Whoever
needs every kind (presets, training, loading a model, the bench, tuning) imports this module; a kind
declared elsewhere (a test's toy, a user's own) is appended after them. A new kind is one module
plus its tests, added to the imports below (``docs/extending.md``).
"""
from __future__ import annotations

from . import nets, delan  # noqa: F401  (they declare the built-in kinds, in this order)
from .kind_registry import (BUDGET_STEPS, DELAN_PARTS, KINDS, NET_PARTS, NETWORK_KINDS, SPACE, NetworkKind,
                            build_net, build_parts, clips_gradients, cost_rank, fast_net_front, network_kind,
                            preset_problems, register, search_fc, unregister)
from .nets import single_net

__all__ = ["BUDGET_STEPS", "DELAN_PARTS", "KINDS", "NETWORK_KINDS", "NET_PARTS", "NetworkKind", "SPACE", "build_net",
           "build_parts", "clips_gradients", "cost_rank", "fast_net_front", "network_kind", "preset_problems",
           "register", "search_fc", "single_net", "unregister"]
