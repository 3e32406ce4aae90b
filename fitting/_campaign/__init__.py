"""Campaigns: a kite model and its measured cases (loads, markers, lengths) in one TOML file;
the cases solved, scored against their markers and written (``jaxtube shape``)."""
