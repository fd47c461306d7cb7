"""Identification of the dynamic parameters from data.

Bottom to top: :mod:`.regressor` (``τ = Y(q, q̇, q̈) π`` with named column blocks),
:mod:`.base` (base parameters: the identifiable combinations), :mod:`.compression` (per-joint R
factors, so solvers never see N rows), :mod:`.statistics` (coloured-noise covariances),
:mod:`.solver` (the cvxpy status contract), :mod:`.constraints` and :mod:`.priors` (LMIs and
prior penalties of one body), :mod:`.sdp` (the consistent semidefinite program),
:mod:`.identify` (the ``identify`` entry: OLS / WLS / SDP), :mod:`.result` and
:mod:`.summary` (results and their tables), :mod:`.scoring` (held-out scores, fixed models).
"""
