# Sourced by the training recipes: makes data/synth (2000 synthesized clips) and data/salsa (the
# CMU salsa pairs, when ../shared/data/cmu_salsa is there; take 10 is the held-out test pair)
# and sets DATA_ARGS to the train command's data flags.
SALSA=../shared/data/cmu_salsa
DATA_ARGS=(--data data/synth)
[ -f data/synth/index.json ] || sketch2colab synth -o data/synth --clips 2000 --seed 0
if [ -d "$SALSA" ]; then
    mkdir -p data/salsa
    for t in 01 02 03 04 05 06 07 09 10; do
        [ -f data/salsa/60_${t}_61_${t}.npz ] || sketch2colab import-bvh "$SALSA/60_$t.bvh" "$SALSA/61_$t.bvh" \
            -o data/salsa/60_${t}_61_${t}.npz --fps 20
    done
    DATA_ARGS+=(--real data/salsa)
fi
