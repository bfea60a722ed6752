"""The data the client hands back, for annotating code that passes it on.

Clients, sessions and jobs return these; you read them and rarely build them. The package's
top level re-exports the few that user code names often (MeshInfo, LoadProgress, RelationBatch,
JobResult); the rest are here only:

    from actopo.types import SessionStats

    def report(stats: SessionStats) -> str:
        return f"{stats.engine.hit_rate:.0%} hits, {stats.engine.wait_seconds:.3f} s waited"
"""

from actopo._diagram import DiagramGrid, PersistenceCurve, PersistenceDiagram
from actopo._distances import DistanceMatrix
from actopo._mesh import MeshArrays
from actopo._results import FieldResult, JobResult
from actopo._simplified import SimplifiedField
from actopo._tracking import Trajectories
from actopo._tree import Tree, TreeArcs, TreeBranches, TreeNodes, TreeSegmentation
from actopo._types import (
    Counter,
    EngineOptions,
    EngineStats,
    FailedItem,
    FieldInfo,
    JobStats,
    LoadProgress,
    MemoryStats,
    MeshInfo,
    QueryBreakdown,
    RelationBatch,
    ServerInfo,
    ServerLimits,
    SessionInfo,
    SessionStats,
    SimplexRelation,
    StreamItem,
)

__all__ = [
    "Counter", "DiagramGrid", "DistanceMatrix", "EngineOptions", "EngineStats", "FailedItem",
    "FieldInfo", "FieldResult", "JobResult", "JobStats", "LoadProgress", "MemoryStats",
    "MeshArrays", "MeshInfo", "PersistenceCurve", "PersistenceDiagram", "QueryBreakdown",
    "RelationBatch", "ServerInfo", "ServerLimits", "SessionInfo", "SessionStats",
    "SimplexRelation", "SimplifiedField", "StreamItem", "Trajectories", "Tree", "TreeArcs",
    "TreeBranches", "TreeNodes", "TreeSegmentation",
]
