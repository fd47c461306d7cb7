"""Estimates built on an identification: standard parameters from base coefficients
(:mod:`.recover`), a payload on the flange (:mod:`.payload`) and the direction of gravity in a
tilted base (:mod:`.mounting`)."""
