"""Generate, verify or preview a synthetic AirFisheye dataset (thin wrapper of ``airfisheye_bench.synth.cli``).

python scripts/generate_synthetic.py preset=tiny out=DIR [seed=0 workers=2 verify=true contact_sheet=true]
python scripts/generate_synthetic.py verify root=DIR
python scripts/generate_synthetic.py presets
"""

import sys

from airfisheye_bench.synth.cli import main

if __name__ == "__main__":
    sys.exit(main())
