"""How each type looks: a primitive shape and a colour per object type, a colour per furniture type.

The houses carry no meshes (nothing may be downloaded), so every category is drawn from
primitives with a fixed, distinct colour; the segmentation map, not the colour, is the ground
truth of what a pixel shows.
"""

from __future__ import annotations

import colorsys
import hashlib

RGB = tuple[float, float, float]

# Pickupable objects: (shape, colour). Shapes: box, cylinder (upright), sphere, flat (thin box).
OBJECT_LOOKS: dict[str, tuple[str, RGB]] = {
    "AlarmClock": ("box", (0.85, 0.2, 0.2)),
    "AluminumFoil": ("cylinder", (0.8, 0.8, 0.85)),
    "Apple": ("sphere", (0.8, 0.05, 0.05)),
    "BaseballBat": ("cylinder", (0.75, 0.55, 0.3)),
    "BasketBall": ("sphere", (0.95, 0.45, 0.05)),
    "Book": ("box", (0.15, 0.3, 0.7)),
    "Boots": ("box", (0.35, 0.2, 0.1)),
    "Bottle": ("cylinder", (0.2, 0.6, 0.3)),
    "Bowl": ("cylinder", (0.95, 0.9, 0.75)),
    "Box": ("box", (0.7, 0.55, 0.35)),
    "Bread": ("box", (0.85, 0.65, 0.35)),
    "ButterKnife": ("flat", (0.75, 0.75, 0.78)),
    "CD": ("flat", (0.7, 0.75, 0.9)),
    "Candle": ("cylinder", (0.98, 0.95, 0.85)),
    "CellPhone": ("flat", (0.1, 0.1, 0.12)),
    "Cloth": ("flat", (0.6, 0.3, 0.6)),
    "CreditCard": ("flat", (0.1, 0.5, 0.8)),
    "Cup": ("cylinder", (0.95, 0.95, 0.95)),
    "DishSponge": ("box", (0.95, 0.85, 0.1)),
    "Dumbbell": ("cylinder", (0.25, 0.25, 0.28)),
    "Egg": ("sphere", (0.97, 0.93, 0.85)),
    "Footstool": ("box", (0.5, 0.3, 0.2)),
    "Fork": ("flat", (0.8, 0.8, 0.82)),
    "HandTowel": ("flat", (0.3, 0.7, 0.8)),
    "Kettle": ("cylinder", (0.6, 0.6, 0.65)),
    "KeyChain": ("flat", (0.9, 0.75, 0.2)),
    "Knife": ("flat", (0.6, 0.62, 0.65)),
    "Ladle": ("flat", (0.45, 0.45, 0.5)),
    "Laptop": ("flat", (0.3, 0.3, 0.33)),
    "Lettuce": ("sphere", (0.4, 0.8, 0.3)),
    "Mug": ("cylinder", (0.85, 0.35, 0.2)),
    "Newspaper": ("flat", (0.88, 0.88, 0.84)),
    "Pan": ("cylinder", (0.15, 0.15, 0.15)),
    "PaperTowelRoll": ("cylinder", (0.98, 0.98, 0.98)),
    "Pen": ("flat", (0.1, 0.1, 0.6)),
    "Pencil": ("flat", (0.95, 0.8, 0.1)),
    "PepperShaker": ("cylinder", (0.2, 0.2, 0.2)),
    "Pillow": ("box", (0.9, 0.85, 0.95)),
    "Plate": ("cylinder", (0.97, 0.97, 0.97)),
    "Plunger": ("cylinder", (0.6, 0.1, 0.1)),
    "Pot": ("cylinder", (0.5, 0.5, 0.55)),
    "Potato": ("sphere", (0.65, 0.5, 0.3)),
    "RemoteControl": ("box", (0.12, 0.12, 0.12)),
    "SaltShaker": ("cylinder", (0.95, 0.95, 0.9)),
    "ScrubBrush": ("box", (0.2, 0.6, 0.9)),
    "SoapBar": ("box", (0.95, 0.7, 0.8)),
    "SoapBottle": ("cylinder", (0.5, 0.8, 0.9)),
    "Spatula": ("flat", (0.2, 0.2, 0.2)),
    "Spoon": ("flat", (0.78, 0.78, 0.8)),
    "SprayBottle": ("cylinder", (0.3, 0.5, 0.95)),
    "Statue": ("cylinder", (0.8, 0.75, 0.6)),
    "TableTopDecor": ("sphere", (0.7, 0.3, 0.5)),
    "TeddyBear": ("sphere", (0.6, 0.4, 0.2)),
    "TennisRacket": ("flat", (0.2, 0.7, 0.2)),
    "TissueBox": ("box", (0.4, 0.7, 0.95)),
    "ToiletPaper": ("cylinder", (0.99, 0.99, 0.99)),
    "Tomato": ("sphere", (0.9, 0.15, 0.1)),
    "Towel": ("flat", (0.9, 0.5, 0.5)),
    "Vase": ("cylinder", (0.3, 0.6, 0.7)),
    "Watch": ("flat", (0.8, 0.7, 0.3)),
    "WateringCan": ("cylinder", (0.2, 0.55, 0.25)),
    "WineBottle": ("cylinder", (0.35, 0.05, 0.15)),
}

FURNITURE_COLOURS: dict[str, RGB] = {
    "ArmChair": (0.55, 0.25, 0.2),
    "Bathtub": (0.95, 0.95, 0.97),
    "Bed": (0.55, 0.4, 0.28),
    "Chair": (0.5, 0.35, 0.2),
    "CoffeeMachine": (0.15, 0.15, 0.15),
    "CoffeeTable": (0.45, 0.3, 0.18),
    "CounterTop": (0.85, 0.82, 0.75),
    "Desk": (0.6, 0.45, 0.3),
    "DiningTable": (0.55, 0.38, 0.22),
    "Dresser": (0.65, 0.5, 0.35),
    "FloorLamp": (0.9, 0.85, 0.6),
    "Fridge": (0.92, 0.93, 0.95),
    "GarbageCan": (0.35, 0.4, 0.35),
    "HandTowelHolder": (0.7, 0.7, 0.72),
    "HousePlant": (0.2, 0.55, 0.2),
    "LaundryHamper": (0.75, 0.65, 0.45),
    "Microwave": (0.25, 0.25, 0.27),
    "Ottoman": (0.4, 0.3, 0.45),
    "Safe": (0.3, 0.32, 0.35),
    "ShelvingUnit": (0.7, 0.55, 0.4),
    "SideTable": (0.6, 0.45, 0.3),
    "Sink": (0.8, 0.82, 0.85),
    "Sofa": (0.3, 0.4, 0.6),
    "Stool": (0.55, 0.4, 0.25),
    "StoveBurner": (0.2, 0.2, 0.22),
    "TVStand": (0.35, 0.25, 0.18),
    "Television": (0.05, 0.05, 0.06),
    "Toaster": (0.75, 0.75, 0.78),
    "Toilet": (0.97, 0.97, 0.97),
    "ToiletPaperHanger": (0.7, 0.7, 0.72),
    "TowelHolder": (0.7, 0.7, 0.72),
}

FLOOR_COLOURS: dict[str, RGB] = {
    "Kitchen": (0.78, 0.74, 0.66),
    "LivingRoom": (0.62, 0.45, 0.3),
    "Bedroom": (0.7, 0.55, 0.4),
    "Bathroom": (0.72, 0.8, 0.85),
}
WALL_COLOUR: RGB = (0.93, 0.91, 0.86)
DEFAULT_FLOOR: RGB = (0.6, 0.6, 0.6)


def hashed_colour(name: str) -> RGB:
    """A stable, saturated colour for a type the tables above do not know (ProcTHOR imports)."""
    h = int(hashlib.sha1(name.encode()).hexdigest()[:6], 16) / 0xFFFFFF
    return colorsys.hsv_to_rgb(h, 0.55, 0.8)


def object_look(type_name: str) -> tuple[str, RGB]:
    return OBJECT_LOOKS.get(type_name, ("box", hashed_colour(type_name)))


def furniture_colour(type_name: str) -> RGB:
    return FURNITURE_COLOURS.get(type_name) or hashed_colour(type_name)


def shade(colour: RGB, factor: float) -> RGB:
    """A darker or lighter variant, to tell parts of one piece apart."""
    return tuple(min(1.0, max(0.0, c * factor)) for c in colour)  # type: ignore[return-value]
