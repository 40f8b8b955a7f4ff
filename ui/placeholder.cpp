// Placeholder so that residue_ui has a source until the viewer's files land.
