"""``python -m bgsub`` is the same as the ``bgsub`` command."""

from bgsub.cli import main

raise SystemExit(main())
