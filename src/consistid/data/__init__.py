"""Robot logs in, datasets out.

=====================  =========================================================================
module                 holds
=====================  =========================================================================
``dataset``            :class:`Dataset` (validated ``t, q, dq, ddq, tau`` arrays, segments, NPZ/CSV
                       of its own layout), ``Dataset.from_recording`` (the signal chain)
``recordings``         :func:`load_recording` (any log file → :class:`Recording`: the dataset and
                       the record of every step), ``from_arrays``, ``from_log``, ``from_frame``
``formats/``           the file readers: ``csv``, ``parquet``, ``rosbag`` (ROS 1/2, MCAP),
                       ``matlab``, ``frame`` (pandas), and ``columns`` (the one column mapping)
``chain``              the signal chain on arrays (:func:`run_chain`, :class:`PreprocessOptions`)
``signals``            the chain's public face (:func:`preprocess` → dataset + record) and its
                       blocks, re-exported
``filters``            low-pass, differentiators, Savitzky–Golay, Fourier, Hampel, bandwidth
``timestamps``         units, duplicates and collapsed stamps, gaps, interval-averaged stamps
``resample``           the one resampler (irregular → uniform grid and back; the supported rate)
``checks``             checks before identification (magnitudes, motion, dead channels, glitches)
=====================  =========================================================================

Imports go one way: ``timestamps``, ``resample``, ``filters`` → ``chain`` → ``dataset`` →
``signals``, ``checks``; ``formats`` → ``recordings``.
"""
