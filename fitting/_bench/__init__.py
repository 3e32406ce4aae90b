"""The bench: the test rig as a jaxtube model (:mod:`.rig`), the effects it can carry
(:mod:`.effects`), the pivot scaling of the fitted law (:mod:`.scaling`) and the planar route
of the statically determinate cantilever (:mod:`.planar`)."""
