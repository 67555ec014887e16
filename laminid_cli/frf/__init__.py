"""FRF data: file formats (store, io) and the rational fraction polynomial fitter (rfp)."""
