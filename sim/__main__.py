import sys

if sys.argv[1:2] == ["system"]:             # the system simulation (sim/system/run.py)
    from sim.system.run import main as system_main
    raise SystemExit(system_main(sys.argv[2:]))

from sim.cli.main import main

raise SystemExit(main())
