"""``python -m bgsub`` is the same as the ``bgsub`` command."""

import sys

try:
    # Importing bgsub loads numpy (about a tenth of a second): Ctrl-C then is no traceback
    # either, as it is nowhere else in the command.
    from bgsub.cli import main
except KeyboardInterrupt:
    if __name__ != "__main__":
        raise
    print("bgsub: interrupted", file=sys.stderr)
    raise SystemExit(130) from None

# The guard matters: `bgsub bench --memory` starts its children with "spawn", which imports
# the parent's __main__ again (as __mp_main__) and must not run the command a second time.
if __name__ == "__main__":
    raise SystemExit(main())
