"""The robot link: a typed robot API over the serial protocol, observers of where the robot
really is, and PAL's robot side on top of them.

Layers: ``pac_protocol`` (transport, codec, exchange) -> :mod:`.api` (typed robot commands) ->
:mod:`.observers` / :mod:`.placement` (where the robot is; how it gets to a start pose) ->
:mod:`.linked` (PAL's tests on the robot) -> the evolve and measure commands. Nothing here
prints or prompts: prompts are callbacks the command line provides.
"""
