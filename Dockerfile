# gearwatch: one image for the API and the Dramatiq workers (docker-compose.yml picks the command).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

RUN useradd --create-home --uid 1000 gearwatch
WORKDIR /app

# Dependencies first so that code edits do not re-install them.
COPY pyproject.toml README.md ./
COPY gearwatch/__init__.py gearwatch/
COPY gearwatch/floor/__init__.py gearwatch/floor/version.py gearwatch/floor/
RUN pip install --upgrade pip && pip install -e . && pip uninstall -y gearwatch

# The source tree, installed in place so that the dashboard's static files (service/static/**)
# and the alembic migrations are served from the same tree.
COPY . .
RUN pip install --no-deps -e . \
    && mkdir -p /data/raw-store \
    && chown -R gearwatch:gearwatch /data

USER gearwatch
ENV GEARWATCH_RAW_STORE=/data/raw-store
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s --retries=3 \
    CMD python -c "import urllib.request,sys; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/health').status != 200)"
CMD ["gearwatch", "serve", "--host", "0.0.0.0", "--port", "8000"]
