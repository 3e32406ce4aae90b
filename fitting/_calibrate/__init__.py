"""Calibration: the least-squares problem and its optimiser (:mod:`.problem`), how the
optimiser ended (:mod:`.outcome`), the fit from one or several starts (:mod:`.fit`), its result
and parameters file (:mod:`.result`), and reading that file back (:mod:`.parameters_file`)."""
