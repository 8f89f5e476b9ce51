"""``python -m benches.cli``: the ``tablebench`` command."""

import sys

from .main import main

sys.exit(main())
