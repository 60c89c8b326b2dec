"""The closed-loop demo harness: rendered worlds, the pipeline's golden model as the robot's
eyes, the firmware's packet, a damaging radio channel, the base station (``station``) and a
robot that follows its path. It imports ``station``; ``station`` never imports ``sim``."""
