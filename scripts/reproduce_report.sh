#!/usr/bin/env bash
# Re-run every number of docs/results.md: train each quick start on three seeds beside its trivial baseline (the
# committed record docs/quickstart_results.json and the report's generated tables), export the seed-2 runs to ONNX
# with int8 (docs/figures/deployment/), evaluate checkpoints and ONNX models, build the leaderboard and the ring
# plots, and run the occlusion study (on the quickstart rig, and on the occlusion rig with its completion ablation:
# 5 sparse inputs x 5 paired seeds, then the test-time cross-over).
#
#   bash scripts/reproduce_report.sh [OUT=runs/report]
#
# Steps whose output already exists are skipped, so an interrupted run can simply be started again. The records it
# writes go under OUT; copy them over the committed ones under docs/ and run
# `python scripts/quickstart_benchmark.py --readme` to regenerate the README's and the report's tables.
# On a 2-core CPU the nine quick-start trainings take about three hours on an otherwise idle machine. The
# occlusion-rig ablation is sized by OCCLUSION_ABLATION (Hydra overrides for train.py; default: 128^2, 5 epochs);
# at the paper's 512^2 it wants a GPU, e.g. OCCLUSION_ABLATION="data.camera.size=512 trainer=gpu trainer.max_epochs=25".
set -euo pipefail
OUT=${1:-runs/report}
OCCLUSION_ABLATION=${OCCLUSION_ABLATION:-data.camera.size=128 trainer.max_epochs=5}
mkdir -p "$OUT/eval"

train() {  # name, overrides...
  local name=$1; shift
  [ -f "$OUT/$name/results.json" ] || python train.py "$@" hydra.run.dir="$OUT/$name" callbacks.rich_progress_bar=null
}
evaluate_checkpoint() {  # name
  local name=$1
  [ -f "$OUT/eval/${name}_ckpt/results.json" ] || \
    python scripts/evaluate.py ckpt_path="$OUT/$name" name="$name" hydra.run.dir="$OUT/eval/${name}_ckpt"
}
export_and_evaluate_onnx() {  # name
  local name=$1
  [ -f "$OUT/$name/model.onnx" ] || python scripts/export_onnx.py ckpt_path="$OUT/$name" out="$OUT/$name/model.onnx"
  [ -f "$OUT/eval/${name}_onnx/results.json" ] || \
    python scripts/evaluate.py onnx_path="$OUT/$name/model.onnx" name="${name}-onnx" hydra.run.dir="$OUT/eval/${name}_onnx"
}

python scripts/quickstart_benchmark.py --out "$OUT/quickstart" --json "$OUT/quickstart_results.json" \
  --tasks seg depth completion --seeds 0 1 2 --threads 1 --fresh
mkdir -p "$OUT/deployment"
for task in seg depth completion; do
  [ -f "$OUT/deployment/$task.json" ] || python scripts/export_onnx.py ckpt_path="$OUT/quickstart/$task/seed2" \
    out="$OUT/deploy/$task.onnx" quantize=static calib_samples=16 eval_samples=64 \
    report_json="$OUT/deployment/$task.json"
done
# The seed-0 runs under the names the leaderboard and the ring plots use.
for pair in seg:seg depth:depth completion_ordering:completion; do
  name=${pair%%:*} task=${pair##*:}
  [ -e "$OUT/$name" ] || ln -s "quickstart/$task/seed0" "$OUT/$name"
done
# The quick-start rig's occlusion ablation (section 4.5): one epoch per sparse input, the same seed for each.
for method in ordering zbuffer none; do
  train "ablation_${method}_1ep" task=completion data.occlusion=$method trainer.max_epochs=1 seed=0
done
for name in seg depth completion_ordering ablation_ordering_1ep ablation_zbuffer_1ep ablation_none_1ep; do
  evaluate_checkpoint "$name"
done
for name in seg depth completion_ordering; do
  export_and_evaluate_onnx "$name"
done

E="$OUT/eval"
python scripts/leaderboard.py out="$OUT/leaderboard" html="$OUT/leaderboard/leaderboard.html" \
  runs="[$E/seg_ckpt,$E/seg_onnx,$E/depth_ckpt,$E/depth_onnx,$E/completion_ordering_ckpt,$E/completion_ordering_onnx]"
python scripts/plot_rings.py "$OUT/eval/depth_ckpt/results.json" "$OUT/eval/completion_ordering_ckpt/results.json" \
  --labels "AdaBins (image only),NLSPN + LiDAR (ordering)" \
  --metric abs_rel --title "Depth AbsRel by incidence angle, synthetic quickstart test split" --out "$OUT/absrel_by_ring.svg"
python scripts/plot_rings.py "$OUT/eval/seg_ckpt/results.json" --labels "DeepLabV3+ / ResNet18" --metric mIoU \
  --title "mIoU by incidence angle, synthetic quickstart test split" --out "$OUT/miou_by_ring.svg"
python scripts/occlusion_study.py --preset quickstart --split test --json "$OUT/occlusion_study.json" \
  --figure "$OUT/occlusion_overlay.png"

# The occlusion rig (preset=occlusion: camera 0.8 m beside and below the LiDAR, 64 x 2048 realistic scans, low
# flights): point level at the served 512^2, then the completion ablation with 3 seeds per method.
python scripts/occlusion_study.py --preset occlusion --split test --size 512 \
  --json "$OUT/occlusion_study_occlusion.json" --figure "$OUT/occlusion_overlay_occlusion.png"
# How much each sparse input differs from `none` at the sizes trained, then the ablation: 5 paired seeds per input
# (the oracle included), paired differences against `none` with 95 % t-intervals, whole image and affected pixels;
# then the test-time cross-over of one of its models (ordering, seed 0) with every input.
python scripts/occlusion_crossover.py --preset occlusion --size 128 256 512 --json "$OUT/occlusion_inputs.json"
# shellcheck disable=SC2086  # OCCLUSION_ABLATION is a list of overrides
python scripts/occlusion_ablation.py --out "$OUT/ablation_occlusion" --seeds 0 1 2 3 4 \
  --json "$OUT/ablation_occlusion.json" -- data.preset=occlusion data.source=fisheye $OCCLUSION_ABLATION \
  callbacks.rich_progress_bar=null
python scripts/occlusion_crossover.py --ckpt "$OUT/ablation_occlusion/ordering/seed0" \
  --json "$OUT/occlusion_crossover.json"
