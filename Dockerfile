# One image for both roles of docker-compose.yml: the API (`freecal serve`) and
# the workers (`freecal worker`). Build: docker build -t freecal .
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    FREECAL_DATA_DIR=/data

WORKDIR /app
# dependencies first (cached while only the code changes)
COPY pyproject.toml README.md ./
COPY calib_core ./calib_core
COPY backend ./backend
COPY frontend ./frontend
RUN pip install --upgrade pip && pip install ".[service]"
# the compiled kernels into numba's cache at build time (about 30 s), not at the first job;
# a cache folder the service's user owns, since numba only reads a cache where it may write
ENV NUMBA_CACHE_DIR=/app/numba-cache
RUN cd / && python -m calib_core.warm_up  # from /: the installed package, the one the service imports
# the page is served from this folder (an installed package does not carry it)
ENV FREECAL_FRONTEND_DIR=/app/frontend

# a non-root user owning the shared data volume
RUN useradd --create-home --uid 1000 freecal && mkdir -p /data && chown freecal /data && chown -R freecal /app/numba-cache
USER freecal
VOLUME ["/data"]
EXPOSE 8000

CMD ["freecal", "serve", "--host", "0.0.0.0", "--port", "8000"]
