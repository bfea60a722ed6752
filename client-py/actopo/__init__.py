"""Python client of the ACTOPO topology service.

Load or upload tetrahedral meshes, open sessions on a topological data structure (explicit,
compact or the task-parallel actopo engine), query relations and run TTK-compatible algorithms
(critical points, discrete gradient, Morse-Smale complex), with numpy in and out.

    import actopo

    with actopo.Client("127.0.0.1:50051") as client:
        mesh = client.load_mesh("fertility_tet.vtu")          # under the server's data dir
        with client.open_session(mesh, scalar="eigenfunction4", structure="actopo") as s:
            offsets, values = s.relation("vertex_edges", [0, 1, 2])
            result = s.run("morse-smale", progress=True)       # Ctrl-C cancels the job
            print(result.summary["critical_cells"], result.stats.engine.wait_seconds)
            print(result.segmentation["MorseSmaleManifold"][:10])

Every failure is an ActopoError; its subclasses name the kind (InvalidMeshError, NotFoundError,
ResourceExhaustedError, ...) and keep the gRPC code and the server's message.
"""

from actopo._async_client import AsyncClient, AsyncJob, AsyncSession
from actopo._client import Client, Job, Session
from actopo._errors import (
                            ActopoError,
                            AuthenticationError,
                            CancelledError,
                            DeadlineExceededError,
                            FailedPreconditionError,
                            InvalidArgumentError,
                            InvalidMeshError,
                            NotFoundError,
                            OutOfRangeError,
                            ResourceExhaustedError,
                            UnavailableError,
)
from actopo._results import JobResult
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

__version__ = "0.1.0"

__all__ = [
    "ActopoError", "AsyncClient", "AsyncJob", "AsyncSession", "AuthenticationError",
    "CancelledError", "Client", "Counter", "DeadlineExceededError", "EngineOptions",
    "EngineStats", "FailedItem", "FailedPreconditionError", "FieldInfo", "InvalidArgumentError",
    "InvalidMeshError", "Job", "JobResult", "JobStats", "LoadProgress", "MemoryStats",
    "MeshInfo", "NotFoundError", "OutOfRangeError", "QueryBreakdown", "RelationBatch",
    "ResourceExhaustedError", "ServerInfo", "ServerLimits", "Session", "SessionInfo",
    "SessionStats", "SimplexRelation", "StreamItem", "UnavailableError", "__version__",
]
