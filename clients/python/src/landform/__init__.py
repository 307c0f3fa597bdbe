"""Landform: a Python client of the Landform terrain-generation service.

    from landform import Client
    client = Client("http://127.0.0.1:8080", api_key=None)
    job = client.submit("bulldoze", body)
    job.wait()                                  # a tqdm bar; raises JobFailed / JobCancelled
    job.artifact("mesh.glb", "mesh.glb")
"""

from . import _types as types
from ._client import ROUTES, Client, Job, JobDocument, JobPage
from ._errors import JobCancelled, JobError, JobFailed, LandformError, LandformProblem
from ._sse import Event
from ._types import KINDS, REQUEST_BODIES, Kind, Problem

__version__ = "0.1.0"

__all__ = [
    "Client",
    "Event",
    "Job",
    "JobCancelled",
    "JobDocument",
    "JobError",
    "JobFailed",
    "JobPage",
    "KINDS",
    "Kind",
    "LandformError",
    "LandformProblem",
    "Problem",
    "REQUEST_BODIES",
    "ROUTES",
    "types",
]
