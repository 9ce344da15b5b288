# syntax=docker/dockerfile:1
# The Python pilot base: Python 3.11 with MAVSDK-Python and pymavlink, pinned
# (images/pilot-python.requirements.txt). Extend it with your pilot script
# (docs/pilots.md, "Packaging a pilot for Kubernetes"); images/pilot-examples.Dockerfile is an
# example.
#
# The pilot Job runs it as user 65532 with a read-only root, HOME=/tmp (an emptyDir) and
# the run's files under /etc/sadesim (SADESIM_FLEET, SADESIM_SCENARIO).
#
# Build from the repository root:
#   docker build -f images/pilot-python.Dockerfile -t ghcr.io/sadesim/pilot-python:0.1.0 .
FROM python:3.11-slim-bookworm
COPY images/pilot-python.requirements.txt /tmp/requirements.txt
RUN pip install --no-cache-dir --disable-pip-version-check -r /tmp/requirements.txt \
 && rm /tmp/requirements.txt
# No .pyc next to the code (the root is read-only) and output unbuffered (the pod's log is
# the pilot's log, read as it flies).
ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 HOME=/tmp
WORKDIR /pilot
USER 65532:65532
ENTRYPOINT ["python3"]
