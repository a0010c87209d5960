"""The launch campaign: experiment matrix and order, the campaign loop, calibration of the twin.

- plan: experiment matrix, trial order, operator changes, resume, progress
- runner: the campaign loop over an injected launch and store acknowledgement
- calibration: fit the launch twin's uncertain parameters to physical outcomes
"""
