"""Design sweeps over many specimens (:mod:`.sweep`), their settings and result
(:mod:`.result`) and statuses (:mod:`.status`)."""
