"""Diagnosis of what the model lacks: residual comparison (:mod:`.compare`), score and
likelihood-ratio statistics (:mod:`.score`), blocked cross-validation (:mod:`.validation`),
the decision rule and the ranking of candidate effects (:mod:`.ranking`), refits, plausible
sizes and the backward step (:mod:`.selection`), the loop (:mod:`.diagnosis`), what the data
cannot separate (:mod:`.separation`), the verdict (:mod:`.verdict`) and the report in words
(:mod:`.report`)."""
