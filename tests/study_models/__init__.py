"""Models of the study tests, in a package the study's worker processes import (the tests put
this folder on their PYTHONPATH)."""
