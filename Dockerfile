# Reproduction image for warehouse-marl-bench: runtime dependencies only (no dev extras, no
# tests), CPU-only torch, non-root. Needs BuildKit (Docker >= 20.10: DOCKER_BUILDKIT=1; its
# built-in Dockerfile frontend, no frontend image is pulled). docs/deployment.md has the long form.
#   DOCKER_BUILDKIT=1 docker build -t warehouse-marl-bench .
#   docker run --rm --shm-size=2g --user "$(id -u):$(id -g)" -v "$PWD/results:/results" warehouse-marl-bench
# Build arguments and inputs:
#   BASE_IMAGE       a Debian-like image with python3 (3.11) and python3 -m venv (default python:3.11-slim)
#   TORCH_INDEX_URL  where pip finds torch==2.13.0 when docker/wheels/ holds no torch wheel
#   docker/wheels/   torch wheel(s) to install instead (buildx: --build-context torchwheels=DIR)
#   --secret id=pip_ca,src=CA_BUNDLE   a CA bundle for pip behind a TLS-intercepting proxy;
#                    mounted for the install step only, never stored in a layer
ARG BASE_IMAGE=python:3.11-slim

FROM scratch AS torchwheels
COPY docker/wheels/ /

FROM ${BASE_IMAGE} AS build
ARG TORCH_INDEX_URL=https://download.pytorch.org/whl/cpu
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1 PYTHONDONTWRITEBYTECODE=1
RUN python3 -m venv /opt/venv
WORKDIR /src
COPY pyproject.toml constraints.txt ./
# torch first, exactly 2.13.0 (a local wheel when given, else the CPU index), then the
# runtime dependencies of pyproject.toml under constraints.txt (the versions the host uses);
# the package itself comes last, so a code change reuses this layer (the build cache).
RUN --mount=type=secret,id=pip_ca --mount=type=bind,from=torchwheels,target=/wheels \
    set -eu; \
    if [ -s /run/secrets/pip_ca ]; then export PIP_CERT=/run/secrets/pip_ca; fi; \
    wheel="$(find /wheels -name 'torch-2.13.0*.whl' -print -quit)"; \
    if [ -n "$wheel" ]; then /opt/venv/bin/pip install --quiet "$wheel"; \
    else /opt/venv/bin/pip install --quiet "torch==2.13.0" --index-url "$TORCH_INDEX_URL"; fi; \
    python3 -c "import tomllib; print(*tomllib.load(open('pyproject.toml', 'rb'))['project']['dependencies'], sep='\n')" > /tmp/runtime.txt; \
    /opt/venv/bin/pip install --quiet -c constraints.txt -r /tmp/runtime.txt; \
    rm -rf /opt/venv/lib/python3*/site-packages/torch/include
COPY README.md ./
COPY envs ./envs
COPY algorithms ./algorithms
COPY bench ./bench
COPY studies ./studies
COPY reports ./reports
COPY paper ./paper
RUN --mount=type=secret,id=pip_ca \
    if [ -s /run/secrets/pip_ca ]; then export PIP_CERT=/run/secrets/pip_ca; fi; \
    /opt/venv/bin/pip install --quiet --no-deps .
# Size (docs/deployment.md, the image): the packages' own test suites, C++ headers,
# Ray's Java jars and libraries the bench never imports (RLlib, Data, Serve, Tune, Train),
# and the byte code of modules a run does not load (docker/prune_pyc.py).
WORKDIR /opt/venv/lib/python3.11/site-packages
RUN find . -depth -type d \( -name tests -o -name test \) -prune -exec rm -rf {} + \
    && rm -rf ray/jars ray/rllib ray/data ray/serve ray/tune ray/train ray/llm ray/workflow pyarrow/include
COPY docker/prune_pyc.py /tmp/prune_pyc.py
RUN /opt/venv/bin/python /tmp/prune_pyc.py

FROM ${BASE_IMAGE}
ENV PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1 \
    PATH=/opt/venv/bin:$PATH \
    HOME=/home/bench \
    MPLBACKEND=Agg
# HOME is world-writable (sticky) so that any --user uid:gid has a home for ~/.ray/auth_token.
RUN useradd --uid 1000 --home-dir /home/bench --create-home bench \
    && chmod 1777 /home/bench \
    && mkdir -p /results && chown bench:bench /results
COPY --from=build /opt/venv /opt/venv
USER 1000:1000
WORKDIR /results
VOLUME ["/results"]
ENTRYPOINT ["bench"]
CMD ["run", "--grid", "smoke", "--out", "/results/smoke"]
