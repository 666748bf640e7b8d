# Reproduction image for warehouse-marl-bench: CPU-only torch, pinned dependencies, non-root.
# Build:  docker build -t warehouse-marl-bench .
# Run:    docker run --rm --shm-size=2g -v "$PWD/results:/results" warehouse-marl-bench
#         (default command: the smoke grid into /results/smoke; then `report --run /results/smoke`)
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    VENV=/opt/venv \
    PATH=/opt/venv/bin:$PATH \
    TORCH_INDEX_URL=https://download.pytorch.org/whl/cpu

RUN useradd --create-home --uid 1000 bench \
    && mkdir -p /results /app \
    && chown bench:bench /results /app

WORKDIR /app
COPY --chown=bench:bench pyproject.toml constraints.txt README.md ./
COPY --chown=bench:bench scripts ./scripts
COPY --chown=bench:bench envs ./envs
COPY --chown=bench:bench algorithms ./algorithms
COPY --chown=bench:bench bench ./bench
COPY --chown=bench:bench studies ./studies
COPY --chown=bench:bench reports ./reports
COPY --chown=bench:bench tests ./tests

# The same setup recipe as the README and CI: torch (CPU build) first, then the package.
RUN bash scripts/setup.sh && chown -R bench:bench /opt/venv

USER 1000:1000
VOLUME ["/results"]
ENTRYPOINT ["bench"]
CMD ["run", "--grid", "smoke", "--out", "/results/smoke"]
