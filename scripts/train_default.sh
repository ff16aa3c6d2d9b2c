#!/usr/bin/env bash
# The recipe behind resources/models/default.pt, sized for a 2-core CPU: about six hours there
# (VQ-VAE ~1 h, teacher ~2.5 h, student ~2.3 h, preview ~0.9 h; see the model card). Resumable: run it again after
# an interruption and it continues (finished stages are skipped, a stage in progress resumes from
# its last checkpoint), so it also runs in pieces, e.g. `timeout 2h bash scripts/train_default.sh`
# repeated. Stages that do not depend on each other run side by side, one thread each. Needs
# ../shared/data/cmu_salsa for the real pairs (skipped if absent).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
export PATH="$PWD/.venv/bin:$PATH"
source scripts/training_data.sh
ARGS=("${DATA_ARGS[@]}" --runs runs)

stage() {  # stage NAME STEPS THREADS
    [ -f "runs/$1/final.pt" ] || sketch2colab train "$1" "${ARGS[@]}" --steps "$2" --threads "$3" --resume
}

stage vqvae 8000 2 & stage encoders 1000 1 & wait
stage teacher 14000 2 & { stage ctmc 500 1; stage surrogate 300 1; stage potential 400 1; } & wait
stage student1 13000 2
stage student2 600 2
# The preview student distills student2's guided ODE into 4 jumps; synthesized storyboards only
# (it learns the student's map, not motion).
[ -f runs/preview/final.pt ] || sketch2colab train preview --data data/synth --runs runs --steps 2500 --threads 2 --resume
sketch2colab bundle --runs runs -o resources/models/default.pt "${DATA_ARGS[@]}" \
    --command "bash scripts/train_default.sh"
