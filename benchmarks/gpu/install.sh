# Sourced by the run scripts, from the repository root on the lent machine: the glvnd loaders
# (.gl/*.deb) unpacked over /, NVIDIA's EGL vendor file named where the image keeps it apart,
# and pipegen with the wheels it needs (.whl/) installed into $SITE, PYTHONPATH pointing there.
# KEEP_SITE=1 keeps an install already in $SITE (a second call to a machine still warm).
# DRY=1 (a local dry run) does none of it: the scripts then run this checkout's pipegen.
if [ -z "${DRY:-}" ]; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig
    j=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
    if [ -f "$j" ] && ! ls /usr/share/glvnd/egl_vendor.d/*nvidia* >/dev/null 2>&1; then
        export __EGL_VENDOR_LIBRARY_FILENAMES=$j
    fi
    if [ -z "${KEEP_SITE:-}" ] || [ ! -d "$SITE/pipegen" ]; then
        rm -rf "$SITE"
        $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
            --target "$SITE" .whl/*.whl || exit 1
        tar -xJf .whl/pocl.tar.xz -C "$SITE" || exit 1
    fi
    export PYTHONPATH=$SITE
fi
export PYTHONUNBUFFERED=1 PYTHONDONTWRITEBYTECODE=1
