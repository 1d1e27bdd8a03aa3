"""Generate, verify or preview a synthetic AirFisheye dataset (the same as ``airfisheye-generate``).

python scripts/generate_synthetic.py preset=tiny out=DIR [seed=0 workers=2 verify=true contact_sheet=true]
python scripts/generate_synthetic.py verify root=DIR
python scripts/generate_synthetic.py presets
python scripts/generate_synthetic.py --help
"""

import sys

from airfisheye_bench.cli.commands import generate

if __name__ == "__main__":
    sys.exit(generate())
