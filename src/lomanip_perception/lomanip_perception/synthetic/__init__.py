"""Synthetic demonstrations and the 'synthetic' stand-ins of every model role (offline default).

Nothing here is a learned model. The generator draws a posed, articulated human interacting with an
object of the prompt's class (a different instance from the scene's) and keeps its ground truth;
the stand-ins read that ground truth with configurable corruption (depth scale error and noise,
matcher outliers incl. left/right flips, pose joint noise). Everything is named "synthetic" so no
result is mistaken for one of the paper's foundation models.
"""
