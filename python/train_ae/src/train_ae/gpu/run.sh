#!/usr/bin/env bash
# The GPU machine's command: train the `paper` network on the packs in .gpu/ and distil it into
# the `cpu` configuration (started from the shipped weights/cpu.pt, holding out the objects that
# file held out), all within $MINUTES of wall clock, writing into $OUT:
#   $OUT/paper.pt, $OUT/cpu-distilled.pt   train_ae checkpoints (bridge.load, evaluate --ckpt)
#   $OUT/record.json                       how they were made (packs' sha256, settings, rates)
#   $OUT/log.txt                           this script's whole output
# Needs only python3 with torch, numpy and pillow (nothing is installed). Usage, from the
# repository root:  COMMIT=<git sha> OUT=<dir> bash python/train_ae/src/train_ae/gpu/run.sh
# (extra arguments go to `python3 -m train_ae.gpu`; PACKS, MINUTES and PYTHON override).
set -euo pipefail
cd "$(dirname "$0")/../../../../.."
: "${OUT:?set OUT to the output directory}"
mkdir -p "$OUT"
PY=${PYTHON:-python3}
MINUTES=${MINUTES:-7.5}
COMMIT=${COMMIT:-$(git rev-parse HEAD 2>/dev/null || echo unknown)}
WEIGHTS=python/train_ae/src/train_ae/weights/cpu.pt
export PYTHONPATH=python/train_ae/src PYTHONUNBUFFERED=1
packs=()
for f in ${PACKS:-.gpu/*.npz}; do packs+=(--pack "$f"); done
{
  echo "# commit $COMMIT, $(date -u +%FT%TZ), budget $MINUTES min"
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
  ls -l ${PACKS:-.gpu/*.npz}
  "$PY" -c 'import sys, torch, numpy, PIL; print("python", sys.version.split()[0], "torch",
torch.__version__, "cuda", torch.version.cuda, torch.cuda.is_available(), "numpy",
numpy.__version__, "pillow", PIL.__version__)'
  "$PY" -m train_ae.gpu "${packs[@]}" --config paper --distill cpu \
    --distill-init "$WEIGHTS" --holdout-from "$WEIGHTS" \
    --minutes "$MINUTES" --out "$OUT" --commit "$COMMIT" "$@"
} 2>&1 | tee "$OUT/log.txt"
