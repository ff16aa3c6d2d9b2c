"""The benchmark (`sketch2colab bench`): protocol (which storyboards), runner (methods and
per-sample metrics), scores, targets, speed, diagnostics, plots, report; suite ties them together."""
