"""Pure-numpy algorithms of the paper (no Drake import, except :mod:`akc_drake.core.coik`)."""
