"""A stand-in for a library that takes a while to import (as VTK does): imported by ``slow_import_mc``."""

import time

#: seconds its import takes
IMPORT_SECONDS = 0.5

time.sleep(IMPORT_SECONDS)
