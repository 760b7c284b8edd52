# fleetplan service image: REST API, browser page, planner workers, MAVLink GCS.
# Build: docker build -t fleetplan .   Run: see docker-compose.yml (service + PX4 SITL fleet).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1

WORKDIR /src
COPY pyproject.toml README.md ./
COPY planner ./planner
COPY gcs ./gcs
COPY web ./web
# A wheel install: the page ships inside the package (gcs/web), no source tree needed.
RUN pip install --upgrade pip && pip install . && rm -rf /src

RUN useradd --create-home --uid 1000 fleetplan && mkdir -p /data && chown fleetplan /data
USER fleetplan
WORKDIR /data
VOLUME ["/data"]

# 8000: HTTP (API + page). 14540/udp: MAVLink from the vehicles' offboard links.
EXPOSE 8000 14540/udp
ENV FLEETPLAN_HOST=0.0.0.0 \
    FLEETPLAN_PORT=8000 \
    FLEETPLAN_DATABASE_URL=sqlite:////data/fleetplan.db
# Bound to 0.0.0.0 inside the container, the service needs an operator token: pass
# FLEETPLAN_API_TOKEN or FLEETPLAN_API_TOKEN_FILE (see the README's Access control).
HEALTHCHECK --interval=10s --timeout=3s --start-period=20s \
    CMD python -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=2)"
ENTRYPOINT ["fleetplan", "serve"]
# Without a fleet file the service starts mock vehicles (FLEETPLAN_MOCK_VEHICLES, default 4).
CMD []
