import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from simtest import make_scenario, run_controller  # noqa: F401  (fixtures)
