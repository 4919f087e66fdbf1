"""`python -m featherstar.hil emulate ...`: the hil commands without the rest of featherstar."""
import sys

from .cli import main

sys.exit(main())
