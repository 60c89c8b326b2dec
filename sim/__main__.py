import sys

if sys.argv[1:2] == ["system"]:             # the system simulation (sim/system.py)
    from .system import main as system_main
    raise SystemExit(system_main(sys.argv[2:]))

from .cli import main

raise SystemExit(main())
