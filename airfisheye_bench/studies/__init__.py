"""The study code: what the benchmark and study scripts of ``scripts/`` run, under public names, so that tests import
it.

Each ``scripts/<name>.py`` is a thin entry point to one module here (``bench_evaluate`` ->
:mod:`~.evaluation_speed`, ``bench_lightning`` -> :mod:`~.lightning_overhead`, ``bench_loader`` ->
:mod:`~.loader_speed`, ``bench_multi_source`` -> :mod:`~.multi_source_cost`, ``bench_occlusion_memory`` ->
:mod:`~.occlusion_memory`, ``occlusion_study``, ``occlusion_ablation``, ``gpu_campaign`` -> :mod:`~.gpu_campaign`,
which times training steps with :mod:`~.train_throughput` and keeps its time-boxed record with
:mod:`~.campaign_record`, ``check_real_rings`` -> :mod:`~.real_rings`); :mod:`~.lidar_scene` is the analytic LiDAR
scene the LiDAR benchmarks and tests share, :mod:`~.miniature_datasets` the miniature public datasets
(KITTI-360, TartanAir) the dataset benchmarks (``bench_kitti360``, ``bench_tartanair``) and the readers' tests share. The studies' own logic and statistics are here too: the quick-start
benchmark and its report tables (:mod:`~.quickstart`, :mod:`~.quickstart_report`; ``quickstart_benchmark``), the
occlusion cross-over (:mod:`~.crossover`; ``occlusion_crossover``), the ablation's records
(:mod:`~.ablation_records`) and hidden-point detection (:mod:`~.hidden_detection`), paired differences between
training arms (:mod:`~.paired`) and with the flight as the unit (:mod:`~.clustered`), and the ``provenance`` block
of every record (:mod:`~.provenance`).
They run from a checkout: the benchmarks write their tables into its ``docs/benchmarks.md`` and the ablation
drives its ``train.py``. Nothing is imported here: ``occlusion_memory`` measures each method in a fresh
``python -m`` process, which loads only its own module.
"""
