"""Every ActopoError subclass, raised by a real server (or by the client where it decides)."""

from __future__ import annotations

import shutil
import subprocess

import grpc
import pytest
from harness import running_server, wait_until
from meshes import lattice

import actopo


@pytest.fixture(scope="module")
def strict_server():
    """A server with a token and room for one mesh, one session and four engine threads."""
    with running_server("--token", "s3cret", "--max-meshes", "1", "--max-sessions", "1",
                        "--max-engine-threads", "4") as target:
        yield target


def test_invalid_argument(client):
    mesh = client.sample("jittered:4")
    try:
        with client.open_session(mesh) as session:
            with pytest.raises(actopo.InvalidArgumentError) as e:
                session.run("critical-points", parameters={"boundary_rule": "sideways"})
            assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
            assert "sideways" in e.value.details
            with pytest.raises(actopo.InvalidArgumentError) as e:
                session.query("vertex_star", (0, 1))  # two vertices are an edge, not a vertex
            assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
            with pytest.raises(actopo.InvalidArgumentError, match="unknown relation 'vv'"):
                session.relation("vv", [0])  # decided on the client
            with pytest.raises(actopo.InvalidArgumentError, match="unknown algorithm"):
                session.run("reeb-graph")
        with pytest.raises(actopo.InvalidArgumentError, match=r"engine\.consumers"):
            client.open_session(mesh, consumers=1000)
    finally:
        client.delete_mesh(mesh)


def test_invalid_mesh_from_the_server(client):
    with pytest.raises(actopo.InvalidMeshError) as e:
        client.load_mesh("happi_tas_tri.vtu")
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "triangle" in e.value.details
    with pytest.raises(actopo.InvalidMeshError, match="outside the server's data directory"):
        client.load_mesh("../../etc/passwd")


def test_not_found(client):
    for call in (lambda: client.get_mesh("mesh-nope"), lambda: client.delete_mesh("mesh-nope"),
                 lambda: client.get_session("session-nope"),
                 lambda: client.load_mesh("no_such_file.vtu"),
                 lambda: client.cancel_job("job-nope")):
        with pytest.raises(actopo.NotFoundError) as e:
            call()
        assert e.value.code == grpc.StatusCode.NOT_FOUND and e.value.details


def test_out_of_range(client):
    points, tets, fields = lattice(3)
    mesh = client.upload_mesh((points, tets, fields))
    try:
        with client.open_session(mesh) as session:
            with pytest.raises(actopo.OutOfRangeError, match="27") as e:
                session.relation("vertex_star", [0, 27])
            assert isinstance(e.value, IndexError)
            with pytest.raises(actopo.OutOfRangeError):
                session.query("tetrahedron_vertices", mesh.tetrahedra)
    finally:
        client.delete_mesh(mesh)


def test_resource_exhausted_and_authentication(strict_server):
    with actopo.Client(strict_server) as anonymous:
        with pytest.raises(actopo.AuthenticationError) as e:
            anonymous.server_info()
        assert e.value.code == grpc.StatusCode.UNAUTHENTICATED
    with actopo.Client(strict_server, token="wrong") as wrong:
        with pytest.raises(actopo.AuthenticationError):
            wrong.list_meshes()
    with actopo.Client(strict_server, token="s3cret") as client:
        mesh = client.sample("jittered:4")
        with pytest.raises(actopo.ResourceExhaustedError):
            client.sample("jittered:5")
        # 1 query producer + 4 consumers with 1 producer each per job > 4 threads: refused
        # when opening, not later when a job cannot start.
        with pytest.raises(actopo.InvalidArgumentError, match="engine threads"):
            client.open_session(mesh, consumers=4, producers=1)
        with client.open_session(mesh, consumers=1, producers=1) as session:
            session.run("critical-points")
            with pytest.raises(actopo.ResourceExhaustedError) as e:
                client.open_session(mesh)  # a second session
            assert e.value.code == grpc.StatusCode.RESOURCE_EXHAUSTED


def test_unavailable():
    with actopo.Client("127.0.0.1:9", timeout=10) as client:  # > ~3 s of retries
        with pytest.raises(actopo.UnavailableError) as e:
            client.list_meshes()
        assert e.value.code == grpc.StatusCode.UNAVAILABLE


def test_cancelled_and_deadline(shared_server, client):
    """The job is held on the server until it is cancelled, and until its deadline has passed."""
    mesh = client.sample("jittered:20")
    try:
        with client.open_session(mesh, structure="compact") as session:
            with shared_server.hold("RunJob") as hold:
                job = session.submit("morse-smale")
                hold.wait_held()
                job.cancel()
                hold.release()
                with pytest.raises(actopo.CancelledError) as e:
                    job.result()
            assert e.value.code == grpc.StatusCode.CANCELLED
            with shared_server.hold("RunJob") as hold:
                with pytest.raises(actopo.DeadlineExceededError) as e:
                    session.run("morse-smale", timeout=1.0)
                assert hold.is_held, "the deadline passed while the job was not held"
            assert isinstance(e.value, TimeoutError)
            assert e.value.code == grpc.StatusCode.DEADLINE_EXCEEDED
            wait_until(lambda: session.describe().running_job_id is None,
                       "the session to run no job")
            assert session.run("critical-points", include_arrays=False).summary["counts"]
    finally:
        client.delete_mesh(mesh)


def test_every_error_is_an_actopo_error():
    for name in actopo.__all__:
        value = getattr(actopo, name)
        if isinstance(value, type) and name.endswith("Error"):
            assert issubclass(value, actopo.ActopoError)


def test_tls_with_token(tmp_path):
    openssl = shutil.which("openssl")
    if openssl is None:
        pytest.skip("openssl is needed to make a test certificate")
    key, cert = tmp_path / "key.pem", tmp_path / "cert.pem"
    subprocess.run([openssl, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
                    "-keyout", str(key), "-out", str(cert), "-subj", "/CN=localhost",
                    "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost"],
                   check=True, capture_output=True)
    with running_server("--tls-cert", str(cert), "--tls-key", str(key),
                        "--token", "t0ken") as target:
        credentials = grpc.ssl_channel_credentials(root_certificates=cert.read_bytes())
        with actopo.Client(target, tls=credentials, token="t0ken") as client:
            assert "morse-smale" in client.server_info().algorithms
        with actopo.Client(target, tls=credentials) as client:
            with pytest.raises(actopo.AuthenticationError):
                client.list_meshes()
        with actopo.Client(target, timeout=10) as plaintext:
            with pytest.raises(actopo.UnavailableError):
                plaintext.list_meshes()
