# syntax=docker/dockerfile:1
# The example Python pilots (examples/pilots/*.py) on the Python pilot base: the image the
# piloted examples name in `spec.pilot.image`. Their `command` (`python3
# pilots/<script>.py ...`) runs unchanged in it: the scripts are under /pilot/pilots and the
# working folder is /pilot, as the scenario's folder is locally.
#
# Build from the repository root, after the base:
#   docker build -f images/pilot-python.Dockerfile -t ghcr.io/sadesim/pilot-python:0.1.0 .
#   docker build -f images/pilot-examples.Dockerfile -t ghcr.io/sadesim/pilot-examples:0.1.0 .
ARG BASE=ghcr.io/sadesim/pilot-python:0.1.0
FROM ${BASE}
USER 0
COPY images/pilot-examples.requirements.txt /tmp/requirements.txt
RUN pip install --no-cache-dir --disable-pip-version-check -r /tmp/requirements.txt \
 && rm /tmp/requirements.txt
COPY examples/pilots/*.py /pilot/pilots/
USER 65532:65532
