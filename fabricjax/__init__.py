"""fabricjax: fabric recognition by touch from Minsound, Minsight, a palm microphone and joints."""

__version__ = "0.1.0"
