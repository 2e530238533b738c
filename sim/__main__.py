"""`python -m sim SCENE.toml --duration T ...` = `rodlab sim`."""
import sys

from .cli import sim_main

sys.exit(sim_main())
