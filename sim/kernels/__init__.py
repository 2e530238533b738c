"""The step's numba kernels, by role (imported by module; this package file imports nothing):

    data          the named data they exchange: Params (typed parameter record, LineSearch), RodData, StateArrays,
                  ControlArrays, StepOutput, ContactReport, each built from the Model where it is defined; status
                  codes; the Jacobian's half bandwidths
    workspace     one thread's scratch (Workspace, alloc_workspace) and copy_into
    banded        banded LU and LDLᵀ of the Newton systems
    assemble_3d   the 3-D rod's elements: residual + banded Jacobian, energies
    assemble_2d   the planar rod's elements, and the 3-D frames of a planar state
    newton        the (sub)step written once for both modes (predict, Newton, refresh, accept, integrate, commit)
                  and the decisions the solve takes from the parameters
    ladder        per env: the retry/guard ladder around the (sub)step, then the env's outputs
    batch         step_kernel: the parallel loop over chunks of envs

Their numba options are in :mod:`sim.numba_options`; the contact kernels (sim.contact)
and the geometry below them stay in sim.
"""
