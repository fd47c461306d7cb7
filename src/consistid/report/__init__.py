"""Self-contained HTML reports shared by every result: :mod:`~consistid.report.html` builds the
page (real tables, figures embedded as base64 PNG that fit the page), :mod:`~consistid.report.plots`
the plots several reports draw (torque fits, residual histograms and spectra).

This package sits at the bottom of the layers (it knows numpy and matplotlib, no robot and no
result), so identification, diagnosis and the newer subsystems can all use it.
"""
