"""Training: configs, the resumable (optionally distributed) loop, EMA, checkpoints, and one
task per stage (vqvae, encoders, teacher, student1, student2, potential, ctmc, surrogate)."""
