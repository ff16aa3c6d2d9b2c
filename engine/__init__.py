"""Sketch2Colab engine: storyboard and scene model, data, models, sampler, metrics, CLI.

Never imports Qt or the app package.
"""
