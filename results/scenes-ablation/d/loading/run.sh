#!/bin/bash
# Run the proxies named on the command line (e.g. ./run.sh proxy_d_eta4.4 proxy_c_eta4.4), one
# numba thread each, and write each one's metrics at x = 3.56 m (../../section_metrics.py).
export NUMBA_NUM_THREADS=1
cd "$(dirname "$0")"
for n in "$@"; do
  eulag run $n.toml -o $n.nc --quiet --no-plots > $n.log 2>&1
  python ../../section_metrics.py $n.nc > $n.json 2>> $n.log
done
