"""Build hook: generates the gRPC stubs of the service API while the package is built.

The API lives in ../proto (the only contract between server and clients); nothing generated is
committed. `build_py` runs grpc_tools.protoc on it and writes

    actopo/_proto/actopo/v1/topology_service_pb2.py, _pb2.pyi, _pb2_grpc.py

into the wheel (or into the source tree for an editable install). protoc names the modules after
the proto package, so the generated code imports `actopo.v1...`; that name is taken by this very
package, so putting actopo/_proto on sys.path cannot work. The hook instead rewrites those import
lines to `actopo._proto.actopo.v1...`: the stubs stay private, importable without path tricks,
and the descriptors keep their canonical file names (actopo/v1/topology_service.proto), which
server reflection and other clients agree on.

Where the protos are found: $ACTOPO_PROTO_DIR, else ../proto (a checkout), else ./proto (an
sdist, which carries a copy).

The runtime pins follow the generator: stubs made by grpcio-tools X refuse to import with
grpcio < X, and protobuf's generated code needs a runtime of the same major version. So the
wheel requires `grpcio>=X` and exactly the protobuf range grpcio-tools X itself requires.
"""

from __future__ import annotations

import os
import re
import shutil
from importlib import metadata
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist

HERE = Path(__file__).resolve().parent
PROTO_FILES = ["actopo/v1/topology_service.proto"]
# Used only when grpcio-tools is absent (e.g. a metadata query outside the isolated build).
FALLBACK_PINS = ["grpcio>=1.62", "protobuf>=4.25"]


def proto_root() -> Path:
    env = os.environ.get("ACTOPO_PROTO_DIR")
    candidates = [Path(env)] if env else [HERE.parent / "proto", HERE / "proto"]
    for root in candidates:
        if all((root / f).is_file() for f in PROTO_FILES):
            return root
    raise RuntimeError(
        f"actopo: cannot find {PROTO_FILES[0]} under {', '.join(map(str, candidates))}; "
        "set ACTOPO_PROTO_DIR to the repository's proto/ folder")


def generate_stubs(package_root: Path) -> None:
    """Runs protoc into package_root/actopo/_proto and fixes the generated imports."""
    import grpc_tools
    from grpc_tools import protoc

    out = package_root / "actopo" / "_proto"
    out.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(out / "actopo", ignore_errors=True)
    well_known = Path(grpc_tools.__file__).parent / "_proto"
    root = proto_root()
    args = ["grpc_tools.protoc", f"-I{root}", f"-I{well_known}", f"--python_out={out}",
            f"--pyi_out={out}", f"--grpc_python_out={out}"]
    if protoc.main(args + [str(root / f) for f in PROTO_FILES]) != 0:
        raise RuntimeError(f"actopo: protoc failed on {root}")
    generated = out / "actopo"
    for folder in [generated, *[p for p in generated.rglob("*") if p.is_dir()]]:
        (folder / "__init__.py").write_text("")
    for path in generated.rglob("*.py*"):
        text = path.read_text()
        fixed = re.sub(r"^(from|import) actopo\.", r"\1 actopo._proto.actopo.", text, flags=re.M)
        if fixed != text:
            path.write_text(fixed)


class BuildPyWithStubs(build_py):
    def run(self) -> None:
        super().run()
        # An editable install imports actopo from the source tree, a wheel from build_lib.
        generate_stubs(HERE if getattr(self, "editable_mode", False) else Path(self.build_lib))


class SdistWithProtos(sdist):
    def make_release_tree(self, base_dir: str, files: list[str]) -> None:
        super().make_release_tree(base_dir, files)
        root = proto_root()
        for f in PROTO_FILES:
            target = Path(base_dir) / "proto" / f
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(root / f, target)


def runtime_requirements() -> list[str]:
    try:
        tools_version = metadata.version("grpcio-tools")
        tools_needs = metadata.requires("grpcio-tools") or []
    except metadata.PackageNotFoundError:
        pins = FALLBACK_PINS
    else:
        protobuf = [r.split(";")[0].strip() for r in tools_needs if r.startswith("protobuf")]
        pins = [f"grpcio>={tools_version}", *(protobuf or ["protobuf"])]
    return ["numpy>=1.24", *pins]


setup(
    install_requires=runtime_requirements(),
    cmdclass={"build_py": BuildPyWithStubs, "sdist": SdistWithProtos},
)
