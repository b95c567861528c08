"""Photometric files: IES LM-63 and EULUMDAT read (`files`, the goniometric lights) and written from a far field
(`export`)."""
