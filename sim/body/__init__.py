"""The subject's body: anthropometry, scaling from the static trial, the MjSpec human, virtual
markers, rendering."""
