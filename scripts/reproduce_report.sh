#!/usr/bin/env bash
# Re-run every number of docs/results.md: train the three (scaled) recipes and the occlusion ablation on the
# synthetic quickstart dataset, evaluate each checkpoint, export it to ONNX, evaluate the ONNX model, and build the
# leaderboard, the ring plot and the occlusion study (on the quickstart rig and on the occlusion rig, with its
# completion ablation: every occlusion method x 3 seeds).
#
#   bash scripts/reproduce_report.sh [OUT=runs/report]
#
# Steps whose output already exists are skipped, so an interrupted run can simply be started again.
# On a 2-core CPU the five trainings take about 50 minutes on an otherwise idle machine. The occlusion-rig ablation
# (5 sparse inputs x 5 seeds) is sized by OCCLUSION_ABLATION (Hydra overrides for train.py; default: 128^2, 5 epochs);
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

train seg task=seg
train depth task=depth
train completion_ordering task=completion data.occlusion=ordering
# Occlusion ablation: one epoch each (the 1-epoch ordering run is the same training state as the first epoch of
# completion_ordering: same seed, data order and learning rate).
for method in ordering zbuffer none; do
  train "ablation_${method}_1ep" task=completion data.occlusion=$method trainer.max_epochs=1
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
