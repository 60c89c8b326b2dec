import sys

if sys.argv[1:2] == ["system"]:             # the system simulation (sim/system/command.py)
    from sim.system.command import main as system_main
    raise SystemExit(system_main(sys.argv[2:]))

from sim.cli.main import main

raise SystemExit(main())
