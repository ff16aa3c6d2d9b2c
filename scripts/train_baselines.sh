#!/usr/bin/env bash
# The benchmark's trained comparisons behind resources/models/baselines.pt, trained with the
# shipped bundle's parts (its VQ-VAE normalization, teacher, planner, latent head), on the same
# data and with the same budgets as ours: Sketch2Anim-INT gets the teacher's 14000 steps, the
# parallel-ControlNets ablation's student student1's 13000 and student2's 600 (batch 16 each).
# About 3 h + 1.5 h on a 2-core CPU, one thread each side by side. Resumable like
# train_default.sh: run it again after an interruption and it continues.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
export PATH="$PWD/.venv/bin:$PATH"
source scripts/training_data.sh
# Its own runs folder, seeded from the shipped bundle (the stages the baselines stand on), and the
# bundle's model config (--text: the ablation's student reads the text as ours does).
ARGS=("${DATA_ARGS[@]}" --runs runs_baselines --from-bundle resources/models/default.pt --text)

stage() {  # stage NAME STEPS THREADS
    [ -f "runs_baselines/$1/final.pt" ] || sketch2colab train "$1" "${ARGS[@]}" --steps "$2" --threads "$3" --resume
}

stage sketch2anim 14000 1 & { stage controlnet1 13000 1; stage controlnet2 600 1; } & wait
sketch2colab bundle --baselines --runs runs_baselines -o resources/models/baselines.pt "${DATA_ARGS[@]}" \
    --command "bash scripts/train_baselines.sh"
