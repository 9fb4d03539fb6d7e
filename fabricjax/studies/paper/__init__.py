"""The paper's studies: one per table or figure (ablation, bandwidth, noise, properties, latents)."""
