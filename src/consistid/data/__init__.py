"""Measured data: :class:`~consistid.data.dataset.Dataset` (validated ``t, q, q̇, q̈, τ``), the
signal chain from a raw log (:mod:`.signals`: time stamps, resampling, zero-phase filtering,
differentiation) and the loaders of robot logs (:mod:`.recordings` and the file formats)."""
