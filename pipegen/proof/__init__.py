"""What proves a build: ``compare`` (two renders, target by target, within the tolerance
scheme), ``check`` (GL against CL), ``precision`` and ``accuracy`` (against the float64
references)."""
