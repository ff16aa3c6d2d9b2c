#!/usr/bin/env bash
# The preview student of resources/models/default.pt, distilled again into the jumps the code asks
# for (engine/models/preview.py PREVIEW_STEPS) from the bundle's own student: about 27 minutes on
# one core of a 2-core CPU (see the model card). Synthesized storyboards only (it learns the
# student's map, not motion). Resumable like the other recipes.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
export PATH="$PWD/.venv/bin:$PATH"
source scripts/training_data.sh
BASE=${1:-resources/models/default.pt}
[ -f runs_preview/preview/done.1000 ] || { sketch2colab train preview --data data/synth --runs runs_preview --text \
    --threads 1 --resume --steps 1000 --warm-start --sparse-share 0.5 --from-bundle "$BASE" \
    && touch runs_preview/preview/done.1000; }
sketch2colab bundle --runs runs_preview -o resources/models/default.pt "${DATA_ARGS[@]}" \
    --command "bash scripts/train_default.sh; bash scripts/train_text.sh; bash scripts/train_preview.sh"
