"""What people read and look at, derived from the IR and from renders: the compile
``report``, ``info``, the pass ``graph`` (DOT), ``visualize`` (targets as pictures) and
``outputs`` (PNG and ``.npy`` files of a render)."""
