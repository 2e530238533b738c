"""Helpers the tests import (not tests themselves): scene specs built in code, static relaxation, contact kernels
outside the solver, the golden-trajectory generators, hostile policy files, synthetic fit data, training args."""
