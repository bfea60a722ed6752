"""Python client of the ACTOPO topology service.

Load or upload tetrahedral meshes and add fields to them, open sessions on a topological data
structure (explicit, compact or the task-parallel actopo engine), query relations and run
TTK-compatible algorithms (critical points, discrete gradient, Morse-Smale complex, persistence
diagram, topological simplification, merge and contour trees) on one field or over many, and the
distances between the fields' persistence diagrams, with numpy in and out.

    import actopo

    with actopo.Client("127.0.0.1:50051") as client:
        mesh = client.load_mesh("fertility_tet.vtu")          # under the server's data dir
        with client.open_session(mesh, scalar="eigenfunction4", structure="actopo") as s:
            offsets, values = s.relation("vertex_edges", [0, 1, 2])
            result = s.run("morse-smale", progress=True)       # Ctrl-C cancels the job
            print(result.summary["critical_cells"], result.stats.engine.wait_seconds)
            print(result.segmentation["MorseSmaleManifold"][:10])

Every failure is an ActopoError; its subclasses name the kind (InvalidMeshError, NotFoundError,
AlreadyExistsError, ResourceExhaustedError, ...) and keep the gRPC code and the server's
message. Structure, Algorithm, Relation, Prefetch and Precompute are the Literal types of the
names the methods take; the statistics and other data the calls return are in actopo.types.
"""

from actopo import types as types  # the returned data types, documented beside __all__
from actopo._async_client import AsyncClient, AsyncJob, AsyncSession
from actopo._client import Client, Job, Session
from actopo._errors import (
                            ActopoError,
                            AlreadyExistsError,
                            AuthenticationError,
                            CancelledError,
                            DataLossError,
                            DeadlineExceededError,
                            FailedPreconditionError,
                            InvalidArgumentError,
                            InvalidMeshError,
                            NotFoundError,
                            OutOfRangeError,
                            ResourceExhaustedError,
                            UnavailableError,
)
from actopo._literals import Algorithm, Precompute, Prefetch, Relation, Structure
from actopo._results import JobResult
from actopo._types import LoadProgress, MeshInfo, RelationBatch

__version__ = "0.1.0"

# The list is documented, one line a name, in README.md ("Public names"); a test compares them.
__all__ = [
    "ActopoError", "Algorithm", "AlreadyExistsError", "AsyncClient", "AsyncJob", "AsyncSession",
    "AuthenticationError", "CancelledError", "Client", "DataLossError", "DeadlineExceededError",
    "FailedPreconditionError", "InvalidArgumentError", "InvalidMeshError", "Job", "JobResult",
    "LoadProgress", "MeshInfo", "NotFoundError", "OutOfRangeError", "Precompute", "Prefetch",
    "Relation", "RelationBatch", "ResourceExhaustedError", "Session", "Structure",
    "UnavailableError", "__version__",
]
