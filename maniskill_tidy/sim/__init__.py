"""House spec -> SAPIEN scene; the camera shader packs this project adds to SAPIEN's."""

from pathlib import Path

SHADERS = Path(__file__).with_name("shaders")
