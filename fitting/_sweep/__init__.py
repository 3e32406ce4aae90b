"""Design sweeps over many specimens (:mod:`.sweep`), on a Dask cluster (:mod:`.cluster`),
their settings and result (:mod:`.result`) and statuses (:mod:`.status`)."""
