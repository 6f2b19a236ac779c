# The render service: `docker build -t pocketray .`, `docker run -p 8000:8000 pocketray`
# (compose.yaml runs several behind a balancer). The entry point is the `pocketray` command.
FROM python:3.11-slim-bookworm

# Headless OpenGL through EGL: libglvnd's loader, Mesa's EGL + llvmpipe (the CPU fallback);
# on an NVIDIA host the container toolkit adds the driver's EGL vendor library.
RUN apt-get update \
 && apt-get install -y --no-install-recommends libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri libgbm1 \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /src
COPY requirements.lock ./
RUN pip install --no-cache-dir -r requirements.lock
COPY pyproject.toml README.md ./
COPY renderer ./renderer
COPY server ./server
COPY shaders ./shaders
COPY client_web ./client_web
RUN pip install --no-cache-dir --no-deps . && rm -rf /src

# State of the sqlite backend (var/ under the working directory) when Redis is not used.
WORKDIR /data
ENV POCKETRAY_HOST=0.0.0.0 POCKETRAY_PORT=8000
EXPOSE 8000
ENTRYPOINT ["pocketray"]
CMD ["serve"]
