"""The finger-sleeve tactile layer: HAPTEX pin renderer and the PHSM perceptual-band model."""
