"""Networks: entity-latent VQ-VAE, temporal U-Net backbone, sketch encoders, diffusion teacher,
rectified-flow student, CTMC phase planner, Jacobian surrogate and learned potential."""
