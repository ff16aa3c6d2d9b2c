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
SALSA=../shared/data/cmu_salsa
ARGS=(--data data/synth --runs runs)

[ -f data/synth/index.json ] || sketch2colab synth -o data/synth --clips 2000 --seed 0
if [ -d "$SALSA" ]; then
    mkdir -p data/salsa
    for t in 01 02 03 04 05 06 07 09 10; do   # take 10 is imported too: it is the held-out test pair
        [ -f data/salsa/60_${t}_61_${t}.npz ] || sketch2colab import-bvh "$SALSA/60_$t.bvh" "$SALSA/61_$t.bvh" \
            -o data/salsa/60_${t}_61_${t}.npz --fps 20
    done
    ARGS+=(--real data/salsa)
fi

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
sketch2colab bundle --runs runs -o resources/models/default.pt "${ARGS[@]:0:2}" "${ARGS[@]:4}" \
    --command "bash scripts/train_default.sh"
