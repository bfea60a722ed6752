# ACTOPO service images, Debian 12 (bookworm) only, apt only (no network but the Debian mirror).
#   server (default target): actopo-server and its mesh reader, their runtime libraries, a
#                            health check
#   client:                  the Python client and `actopo` CLI, from wheels built outside
#                            (scripts/deploy-check.sh: pip wheel ./client-py -w build/wheels)
# Build: podman build --format docker --pull=never --target server -t actopo-server .
#        (--format docker keeps HEALTHCHECK; docker build works as well)

########## build: the same dependencies and CMake build as `make build`, server targets only
FROM debian:bookworm-slim AS build
SHELL ["/bin/bash", "-o", "pipefail", "-c"]
ARG JOBS=2
WORKDIR /src
COPY scripts/install-deps.sh scripts/install-deps.sh
# --no-venv: Debian packages only (no Python environment, no buf/npm).
RUN bash scripts/install-deps.sh --no-venv \
 && rm -rf /var/lib/apt/lists/*
COPY CMakeLists.txt ./
COPY proto proto
COPY server server
COPY tests tests
# The code of `make build` (-O2 -DNDEBUG) without its debug information, which `install -s`
# strips anyway: its compile took 69 s instead of 98 on 2 cores.
RUN cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -DNDEBUG" \
 && cmake --build build -j "${JOBS}" --target actopo-server actopo-read-mesh \
 && install -d /out \
 && install -s -m 0755 build/server/cmd/actopo-server build/server/cmd/actopo-read-mesh /out/

########## client: Python client + CLI (`actopo`), installed offline from copied wheels
FROM debian:bookworm-slim AS client
SHELL ["/bin/bash", "-o", "pipefail", "-c"]
# Debian stable's versions are the pins (DL3008): bookworm only takes fixes.
# hadolint ignore=DL3008
RUN apt-get update \
 && apt-get install -y --no-install-recommends python3 python3-venv \
 && rm -rf /var/lib/apt/lists/*
COPY build/wheels/ /tmp/wheels/
RUN python3 -m venv /opt/actopo \
 && /opt/actopo/bin/pip install --no-cache-dir --no-index --find-links /tmp/wheels actopo \
 && rm -rf /tmp/wheels \
 && groupadd --gid 10001 actopo \
 && useradd --uid 10001 --gid actopo --create-home --home-dir /home/actopo \
      --shell /usr/sbin/nologin actopo
ENV PATH=/opt/actopo/bin:$PATH
USER 10001:10001
WORKDIR /home/actopo
ENTRYPOINT ["actopo"]
CMD ["--help"]

########## server (last, so it is the default target)
FROM debian:bookworm-slim AS server
SHELL ["/bin/bash", "-o", "pipefail", "-c"]
# The runtime libraries of the two binaries (ldd, mapped to packages), plus python3-grpcio for
# the health check (grpc_health_probe is not packaged by Debian).
# hadolint ignore=DL3008
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      libgrpc++1.51 libgrpc29 libprotobuf32 libabsl20220623 libre2-9 libc-ares2 libssl3 \
      libvtk9.1 libtbb12 libdouble-conversion3 liblz4-1 libexpat1 liblzma5 zlib1g libdeflate0 \
      libprometheus-cpp-pull1.0 libprometheus-cpp-core1.0 libcivetweb1 \
      python3-minimal python3-grpcio \
 && rm -rf /var/lib/apt/lists/*
COPY --from=build /out/ /usr/local/bin/
COPY deploy/grpc_health_check.py /usr/local/bin/actopo-health
# Fail the build, not the first start, if a shared library is missing.
RUN groupadd --gid 10001 actopo \
 && useradd --uid 10001 --gid actopo --no-create-home --home-dir /nonexistent \
      --shell /usr/sbin/nologin actopo \
 && install -d -o actopo -g actopo -m 0755 /data \
 && chmod 0755 /usr/local/bin/actopo-health \
 && for b in /usr/local/bin/actopo-server /usr/local/bin/actopo-read-mesh; do \
      if ldd "$b" | grep 'not found'; then echo "missing libraries for $b" >&2; exit 1; fi; \
    done
USER 10001:10001
VOLUME ["/data"]
EXPOSE 50051 9464
HEALTHCHECK --interval=10s --timeout=5s --start-period=30s --retries=3 \
  CMD ["/usr/local/bin/actopo-health", "127.0.0.1:50051"]
ENTRYPOINT ["/usr/local/bin/actopo-server"]
CMD ["--host", "0.0.0.0", "--port", "50051", "--data-dir", "/data", "--metrics-port", "9464"]
