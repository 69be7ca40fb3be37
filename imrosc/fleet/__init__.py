"""Inference over a Dask cluster: each bag a task, per-bag states merged in bag order.

``imrosc infer --scheduler ADDRESS`` (or ``IMROSC_SCHEDULER``) connects to a Dask scheduler
(:func:`connect`) and hands the inference engine a bag reducer (:class:`Fleet`) in place of
its worker processes. Dask is optional: ``pip install 'imrosc[fleet]'``; this package imports
it only when a scheduler is given. ``docs/fleet.md`` says how to run a cluster.
"""

from __future__ import annotations

from imrosc.fleet.cluster import CLUSTER_CONFIG, Fleet, FleetError, connect

__all__ = ["CLUSTER_CONFIG", "Fleet", "FleetError", "connect"]
