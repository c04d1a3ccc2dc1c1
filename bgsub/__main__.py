"""``python -m bgsub`` is the same as the ``bgsub`` command."""

from bgsub.cli import main

# The guard matters: `bgsub bench --memory` starts its children with "spawn", which imports
# the parent's __main__ again (as __mp_main__) and must not run the command a second time.
if __name__ == "__main__":
    raise SystemExit(main())
