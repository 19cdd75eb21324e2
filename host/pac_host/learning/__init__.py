"""Punctuated anytime learning: the PAL loop, the model GA and the model fit."""
