"""Host surfaces the optics are cut into."""
