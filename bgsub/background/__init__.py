"""The background side of the foreground decision: background models (the camera-compensated
one, :mod:`~bgsub.background.compensated`; a sample-based one for a still camera,
:mod:`~bgsub.background.sample`) and the fusion with motion evidence
(:mod:`~bgsub.background.fusion`)."""
