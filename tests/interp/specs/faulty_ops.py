"""Python operations bound by faulty.rssm (a user module next to the specification)."""


def risky(x: float) -> float:
    if x == 3.0:
        raise ValueError("x must not be 3")
    return x * 2.0


def wrong_type(x: float) -> str:
    return f"{x}"
