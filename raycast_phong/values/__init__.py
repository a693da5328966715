"""The scene format's plain value types (fields.py: numbers, vectors, colours with their bounds) and their wording
(messages.py: where a problem is, Location, and how a value is shown): below the kinds of object (shapes/) and the
scene schema (scene/), which are built from them."""
