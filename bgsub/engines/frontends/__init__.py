"""The built-in motion front ends of the moving-camera engine: the gated RBM's patch motion
(:mod:`~bgsub.engines.frontends.grbm`) and Lucas-Kanade corner tracks
(:mod:`~bgsub.engines.frontends.lucas_kanade`)."""
