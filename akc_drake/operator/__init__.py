"""The simulated human operator: model builder, motions, motion-capture file readers."""
