"""The stream stages, in the order data flows through them.

`assembly` (frames of every board -> samples), `calibration` (counts -> deg C), `onset`
(onset and release events), `tracking` and `onset_refine` (decided contacts, each taxel's onset
dated), `pipeline` (the chain, with the classifier) and `sinks` (where results go).
"""
