#!/usr/bin/env python3
"""lab2's command line from anywhere: /usr/bin/python3 tools/lab2/lab2.py ..."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lab2.cli import main  # noqa: E402

sys.exit(main())
