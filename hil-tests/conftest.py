import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from hil import hil  # noqa: F401  (fixture)
