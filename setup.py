"""Package layout beyond ``pyproject.toml``: ``configs/`` ships inside the package as ``airfisheye_bench.configs``.

The Hydra configs stay the top-level ``configs/`` folder of the repository (what ``python train.py`` composes);
installed from a wheel, the same files are ``airfisheye_bench/configs/`` (see
:func:`airfisheye_bench.constants.config_dir`). ``pyproject.toml`` cannot map a package onto a folder outside its
parent's while also finding the packages, hence this file.
"""

from setuptools import find_packages, setup

setup(
    packages=[
        *find_packages(include=["airfisheye_bench*", "datamodules*", "models*"]),
        "airfisheye_bench.configs",
    ],
    package_dir={"airfisheye_bench.configs": "configs"},
    package_data={
        "airfisheye_bench.configs": ["*.yaml", "**/*.yaml"],
        "airfisheye_bench.evaluation.leaderboard": ["assets/*.css", "assets/*.js"],
        "airfisheye_bench.io.datasets": ["woodscape_splits/*.txt"],
    },
)
