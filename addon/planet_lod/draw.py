"""GPU viewport preview (placeholder until shaders land)."""


def register():
    pass


def unregister():
    pass
