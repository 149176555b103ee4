"""The colours of the pictures: contact red (the charts' too), a free string or membrane's blue, the obstacle's
grey, and the yellow edge of a membrane's contact set where it is coloured by a field."""

CONTACT_COLOUR = "#b2182b"
FREE_COLOUR = "#92c5de"
OBSTACLE_COLOUR = "#777777"
MEMBRANE_OBSTACLE_COLOUR = "#c9c9c9"  # OBSTACLE_COLOUR at opacity 0.4 on white
#: the edge of the contact set of a membrane coloured by a field: yellow, seen on blue, grey and red alike
CONTACT_EDGE_COLOUR = "#ffd400"
