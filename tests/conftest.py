"""Property tests explore new cases on a developer's machine; in CI (CI=true) they replay a fixed
set, so that a submission's result does not depend on the draw."""
import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")
