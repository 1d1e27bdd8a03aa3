"""Lightning overhead: one training step through ``lightning.Trainer`` vs a plain PyTorch loop, same model and batch.

The code is :mod:`airfisheye_bench.studies.lightning_overhead` (its docstring says what is measured and how; ``--help``
lists the options).
"""

from airfisheye_bench.studies.lightning_overhead import main

if __name__ == "__main__":
    main()
