"""`python -m sim SCENE.toml --duration T ...` = `rodlab sim`."""
import sys

from sim.cli import sim_main

sys.exit(sim_main())
