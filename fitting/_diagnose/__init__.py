"""Diagnosis of what the model lacks: residual comparison (:mod:`.compare`), score statistics
(:mod:`.score`), the ranking of candidate effects and the loop (:mod:`.ranking`), what the data
cannot separate (:mod:`.separation`) and the report in words (:mod:`.report`)."""
