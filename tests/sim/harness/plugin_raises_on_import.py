"""A plugin module that raises an exception of its own, a BaseException, when imported."""


class ImportTimeFailure(BaseException):
    pass


raise ImportTimeFailure("this module refuses to load")
